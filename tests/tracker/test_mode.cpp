// The mode table, and the contract every mode keeps on every back end: each case runs
// over Combine(all_modes(), all_backends(), shapes), so a new row inherits all of it.
#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <string>

#include "linksight/tracker/mode.hpp"
#include "linksight/tracker/tracker.hpp"
#include "test_support.hpp"

namespace linksight {
namespace {

using sim::ChainShape;

TEST(ModeTable, NamesAreUniqueAndRoundTrip) {
  std::set<std::string> names;
  for (const TrackerMode m : all_modes()) {
    const std::string name(to_string(m));
    EXPECT_FALSE(name.empty());
    EXPECT_FALSE(m.spec().summary.empty()) << name;
    EXPECT_TRUE(names.insert(name).second) << "twice: " << name;
    EXPECT_EQ(parse_mode(name), m);
    EXPECT_EQ(TrackerMode::at(m.index()), m);
  }
  EXPECT_EQ(names.size(), mode_table().size());
  EXPECT_EQ(mode_names().size(), mode_table().size());
  EXPECT_EQ(to_string(TrackerMode{}), "chain-fit");  // the default (issue 17)
  EXPECT_THROW((void)TrackerMode::at(mode_table().size()), std::out_of_range);
}

TEST(ModeTable, ErrorAndChoicesListEveryMode) {
  // Built from the table, so a new row needs no change here.
  EXPECT_EQ(test::error_of<std::invalid_argument>([] { (void)parse_mode("centred"); }),
            "unknown mode 'centred' (expected " + test::expected_modes() + ")");
  EXPECT_EQ(test::expected_modes().rfind("chain-fit, paper, accelerated-som", 0), 0u);
  std::string choices;
  for (const std::string& name : mode_names()) choices += (choices.empty() ? "" : " | ") + name;
  EXPECT_EQ(mode_choices(), choices);
}

// What the table says the modes are made of (docs and the robustness bands rely on it).
TEST(ModeTable, Compositions) {
  const ModeSpec& paper = parse_mode("paper").spec();
  EXPECT_EQ(paper.init.name, "lsq");
  EXPECT_EQ(paper.update.name, "som-mean");
  EXPECT_EQ(paper.reinit.name, "empty-neighbourhood");
  EXPECT_EQ(paper.output.name, "surface");
  const ModeSpec& som = parse_mode("accelerated-som").spec();
  EXPECT_EQ(som.init.name, "som");
  EXPECT_EQ(som.reinit.name, "never");
  const ModeSpec& centred = parse_mode("paper-centred").spec();
  EXPECT_EQ(centred.output.name, "centre-offset");
}

Cloud clean_cloud(const Nodes& truth, std::uint64_t seed, std::vector<int> hidden = {}) {
  sim::SurfaceSampling s;
  s.seed = seed;
  s.noise_sigma = 0.0005;
  s.hidden = std::move(hidden);
  return sim::sample_visible_surface(truth, {}, s);
}

// Ball nodes each nearest their own true ball (the tip node has no ball).
int order_errors(const Nodes& est, const Nodes& truth) {
  int errors = 0;
  for (int j = 0; j < 11; ++j) {
    int nearest = 0;
    for (int k = 1; k < 11; ++k)
      if ((est[j] - truth[k]).norm() < (est[j] - truth[nearest]).norm()) nearest = k;
    errors += nearest != j;
  }
  return errors;
}

using ContractParam = std::tuple<TrackerMode, test::BackendCase, ChainShape>;
class ModeContract : public ::testing::TestWithParam<ContractParam> {
 protected:
  void SetUp() override { LINKSIGHT_SKIP_IF_UNBUILT(std::get<1>(GetParam())); }
  TrackerParams params(const test::BackendCase& backend) const {
    TrackerParams p = test::params_for(backend);
    p.mode = std::get<0>(GetParam());
    return p;
  }
};

// On clean data of a link that bends a little more each frame: nothing lost, every node
// finite, the ball nodes in order, and the back end gives the serial reference's bits.
TEST_P(ModeContract, FiniteOrderedAndBitIdenticalToTheSerialReference) {
  const auto& [mode, backend, shape] = GetParam();
  Tracker tracker(params(backend));
  Tracker reference(params({}));
  for (int f = 0; f < 5; ++f) {
    const Nodes truth = test::test_chain(shape, 0.10 + 0.01 * f);
    const Cloud cloud = clean_cloud(truth, 50 + f);
    const FrameResult r = tracker.step(cloud);
    const FrameResult ref = reference.step(cloud);
    ASSERT_FALSE(r.lost) << "frame " << f;
    ASSERT_EQ(r.nodes.size(), 12u);
    for (const Eigen::Vector3d& q : r.nodes) EXPECT_TRUE(q.allFinite()) << "frame " << f;
    EXPECT_EQ(order_errors(r.nodes, truth), 0) << "frame " << f;
    EXPECT_EQ(r.nodes, ref.nodes) << "frame " << f;
    EXPECT_EQ(r.counts, ref.counts) << "frame " << f;
    EXPECT_EQ(r.reinit, ref.reinit) << "frame " << f;
    EXPECT_EQ(r.iterations, ref.iterations) << "frame " << f;
  }
}

// A lost frame says why, repeats the last output and leaves the state alone: the next
// good frame continues as if the lost one had not been there.
TEST_P(ModeContract, LostFramesRepeatTheOutputAndKeepTheState) {
  const auto& [mode, backend, shape] = GetParam();
  const Nodes truth = test::test_chain(shape);
  Tracker tracker(params(backend));
  Tracker uninterrupted(params(backend));
  const FrameResult first = tracker.step(clean_cloud(truth, 1));
  (void)uninterrupted.step(clean_cloud(truth, 1));
  ASSERT_FALSE(first.lost);
  const FrameResult empty = tracker.step(Cloud{});
  EXPECT_TRUE(empty.lost);
  EXPECT_EQ(empty.lost_reason, LostReason::empty_cloud);
  EXPECT_EQ(empty.nodes, first.nodes);
  EXPECT_TRUE(std::isnan(empty.sdf_error));
  Cloud nan_cloud;
  nan_cloud.xyz = {NAN, 0.0f, 0.5f, 0.1f, INFINITY, 0.5f};
  const FrameResult non_finite = tracker.step(nan_cloud);
  EXPECT_EQ(non_finite.lost_reason, LostReason::all_non_finite);
  EXPECT_EQ(non_finite.nodes, first.nodes);
  const FrameResult next = tracker.step(clean_cloud(truth, 2));
  const FrameResult expected = uninterrupted.step(clean_cloud(truth, 2));
  EXPECT_FALSE(next.lost);
  EXPECT_EQ(next.init_reason, InitReason::none);
  EXPECT_EQ(next.nodes, expected.nodes);
}

std::string contract_name(const ::testing::TestParamInfo<ContractParam>& p) {
  static const char* const kShape[] = {"straight", "C", "S"};
  std::string mode(to_string(std::get<0>(p.param)));
  for (char& c : mode)
    if (c == '-') c = '_';
  return mode + "_" + test::case_name(std::get<1>(p.param)) + "_" +
         kShape[static_cast<int>(std::get<2>(p.param))];
}

INSTANTIATE_TEST_SUITE_P(ModesBackendsShapes, ModeContract,
                         ::testing::Combine(::testing::ValuesIn(all_modes()),
                                            ::testing::ValuesIn(test::all_backends()),
                                            ::testing::Values(ChainShape::straight,
                                                              ChainShape::c_shape,
                                                              ChainShape::s_shape)),
                         contract_name);

// A mode is a composition: a new one needs no change to the tracker. This one, built here
// and thrown away, is the baseline's init and update with the centre-corrected output;
// it must be accelerated-som moved along each viewing ray, frame after frame.
TEST(ModeComposition, AToyModeNeedsOnlyARow) {
  const ModeSpec toy{"toy", "accelerated-som with centre-corrected output", kInitSom,
                     kUpdateSomMean, kReinitNever, kOutputCentreOffset};
  TrackerParams p;
  p.mode = parse_mode("accelerated-som");
  Tracker baseline(p);
  Tracker composed(p, toy);  // params.mode is overridden by the composition
  const double offset = p.policy.centre_offset.fraction * p.geometry.ball_radius;
  const Nodes truth = test::test_chain(ChainShape::c_shape);
  for (int f = 0; f < 6; ++f) {
    // Two balls hidden from frame 3: the toy must not re-initialize (its trigger is never).
    const Cloud cloud = clean_cloud(truth, 70 + f, f >= 3 ? std::vector<int>{4, 5} : std::vector<int>{});
    const FrameResult a = baseline.step(cloud);
    const FrameResult b = composed.step(cloud);
    EXPECT_FALSE(b.reinit);
    EXPECT_EQ(a.counts, b.counts) << "frame " << f;
    for (std::size_t j = 0; j < a.nodes.size(); ++j) {
      const Eigen::Vector3d ray = a.nodes[j].normalized();
      EXPECT_NEAR((b.nodes[j] - a.nodes[j]).dot(ray), offset, 1e-12) << "node " << j;
    }
  }
}

TEST(ModeComposition, PolicySettingsAreValidated) {
  TrackerParams p;
  p.policy.centre_offset.fraction = 1.5;
  EXPECT_EQ(test::error_of<std::invalid_argument>([&] { Tracker t(p); }),
            "centre_offset.fraction = 1.5: must be in [0, 1]");
  p = {};
  p.policy.lsq_init.poly_order = 0;
  EXPECT_NE(test::error_of<std::invalid_argument>([&] { Tracker t(p); }).find("poly_order"),
            std::string::npos);
}

}  // namespace
}  // namespace linksight
