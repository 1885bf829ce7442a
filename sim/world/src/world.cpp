#include "linksight/sim/world.hpp"

#include <BulletDynamics/Featherstone/btMultiBody.h>
#include <BulletDynamics/Featherstone/btMultiBodyDynamicsWorld.h>
#include <BulletDynamics/Featherstone/btMultiBodyJointLimitConstraint.h>
#include <BulletDynamics/Featherstone/btMultiBodyJointMotor.h>
#include <BulletDynamics/Featherstone/btMultiBodyLinkCollider.h>
#include <BulletDynamics/Featherstone/btMultiBodyMLCPConstraintSolver.h>
#include <BulletDynamics/MLCPSolvers/btDantzigSolver.h>
#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace linksight::sim {
namespace {

// Debian builds Bullet with float btScalar.
btVector3 bt(const Eigen::Vector3d& v) {
  return {static_cast<btScalar>(v.x()), static_cast<btScalar>(v.y()), static_cast<btScalar>(v.z())};
}
Eigen::Vector3d eig(const btVector3& v) { return {v.x(), v.y(), v.z()}; }

btTransform bt(const Eigen::Isometry3d& X) {
  const Eigen::Quaterniond q(X.rotation());
  return btTransform(btQuaternion(static_cast<btScalar>(q.x()), static_cast<btScalar>(q.y()),
                                  static_cast<btScalar>(q.z()), static_cast<btScalar>(q.w())),
                     bt(X.translation()));
}

// Bend of a joint whose two bend axes turned by a (about y) then b (about z):
// the angle between the parent's and the child's x axes, cos(theta) = cos(a) cos(b).
double bend_angle(double a, double b) {
  return std::acos(std::clamp(std::cos(a) * std::cos(b), -1.0, 1.0));
}

// Collision groups: the chain collides with the environment only.
constexpr int kChainGroup = 2;
constexpr int kEnvironmentGroup = 1;
// Intermediate links of a joint's three revolute axes: tiny, but with mass and a collider
// (a motor on a link without a collider does nothing in Bullet 3.24).
constexpr double kDummyMass = 1e-3;
constexpr double kDummyRadius = 1e-3;

}  // namespace

double ChainParams::holding_torque() const {
  return friction_coefficient * preload_force * geometry.ball_radius;
}

double ChainParams::worst_gravity_torque(double g) const {
  // Horizontal chain: component k's weight acts k pitches from the base joint (ball 0).
  const int n = geometry.count;
  return component_mass * g * geometry.pitch * (n * (n - 1) / 2.0);
}

void ChainParams::validate() const {
  fields::check(*this, "chain");
  geometry.validate();
  if (geometry.pitch < 2 * geometry.ball_radius)
    fields::fail("chain", "pitch_m", geometry.pitch,
                 "must be >= 2 * ball_radius_m (balls would overlap)");
}

void WorldParams::validate() const { fields::check(*this, "world"); }

struct World::Impl {
  ChainParams chain;
  WorldParams params;
  // Declaration order is destruction order in reverse: the world goes before its parts.
  std::unique_ptr<btDefaultCollisionConfiguration> config;
  std::unique_ptr<btCollisionDispatcher> dispatcher;
  std::unique_ptr<btDbvtBroadphase> broadphase;
  std::unique_ptr<btDantzigSolver> mlcp;
  std::unique_ptr<btMultiBodyMLCPConstraintSolver> solver;
  std::unique_ptr<btMultiBodyDynamicsWorld> world;
  std::unique_ptr<btMultiBody> body;
  std::unique_ptr<btSphereShape> ball_shape, dummy_shape;
  std::unique_ptr<btCapsuleShapeX> neck_shape;
  std::unique_ptr<btCompoundShape> component_shape;  // ball + neck, from ComponentGeometry
  std::vector<std::unique_ptr<btMultiBodyLinkCollider>> colliders;
  std::vector<std::unique_ptr<btMultiBodyJointMotor>> motors;
  std::vector<std::unique_ptr<btMultiBodyJointLimitConstraint>> limits;
  std::vector<ForceAction> actions;
  std::vector<GravityAction> gravity_switches;
  BaseTrajectory trajectory;
  bool has_trajectory = false;
  struct Kinematic {
    std::unique_ptr<btCollisionShape> shape;
    std::unique_ptr<btDefaultMotionState> motion;
    std::unique_ptr<btRigidBody> body;
    BaseTrajectory path;  // empty for static obstacles
  };
  std::vector<Kinematic> environment;
  long long steps = 0;

  void project_onto_cone();

  ~Impl() {
    if (!world) return;
    for (auto& e : environment) world->removeRigidBody(e.body.get());
    for (auto& l : limits) world->removeMultiBodyConstraint(l.get());
    for (auto& m : motors) world->removeMultiBodyConstraint(m.get());
    for (auto& c : colliders) world->removeCollisionObject(c.get());
    if (body) world->removeMultiBody(body.get());
  }
  [[nodiscard]] int links() const { return 3 * chain.geometry.count; }
};

World::World(const ChainParams& chain, const WorldParams& params, const Eigen::Isometry3d& X_WB)
    : impl_(std::make_unique<Impl>()) {
  chain.validate();
  params.validate();
  Impl& s = *impl_;
  s.chain = chain;
  s.params = params;
  s.config = std::make_unique<btDefaultCollisionConfiguration>();
  s.dispatcher = std::make_unique<btCollisionDispatcher>(s.config.get());
  s.broadphase = std::make_unique<btDbvtBroadphase>();
  s.mlcp = std::make_unique<btDantzigSolver>();
  s.solver = std::make_unique<btMultiBodyMLCPConstraintSolver>(s.mlcp.get());
  s.world = std::make_unique<btMultiBodyDynamicsWorld>(s.dispatcher.get(), s.broadphase.get(),
                                                       s.solver.get(), s.config.get());
  s.world->setGravity(btVector3(0, 0, params.gravity ? -params.g : 0.0));

  const ComponentGeometry& g = chain.geometry;
  const int n_links = s.links();
  s.body = std::make_unique<btMultiBody>(n_links, 0.0, btVector3(0, 0, 0), /*fixedBase=*/true,
                                         /*canSleep=*/false);
  const double m = chain.component_mass, r = g.ball_radius;
  const btVector3 I_ball = btVector3(1, 1, 1) * (0.4 * m * r * r);
  const btVector3 I_dummy = btVector3(1, 1, 1) * (0.4 * kDummyMass * kDummyRadius * kDummyRadius);
  for (int k = 0; k < g.count; ++k) {
    for (int a = 0; a < 3; ++a) {
      const int i = 3 * k + a;
      // Joint k pivots at ball centre k, one pitch along the previous component's +x.
      const btVector3 parent_to_pivot =
          (a == 0 && k > 0) ? btVector3(g.pitch, 0, 0) : btVector3(0, 0, 0);
      // Bend about y, bend about z, then twist about the component's own axis x.
      const btVector3 axis = a == 0   ? btVector3(0, 1, 0)
                             : a == 1 ? btVector3(0, 0, 1)
                                      : btVector3(1, 0, 0);
      const bool component = a == 2;
      s.body->setupRevolute(i, component ? m : kDummyMass, component ? I_ball : I_dummy, i - 1,
                            btQuaternion::getIdentity(), axis, parent_to_pivot, btVector3(0, 0, 0),
                            /*disableParentCollision=*/true);
    }
  }
  s.body->finalizeMultiDof();
  s.body->setLinearDamping(0.0);
  s.body->setAngularDamping(0.0);
  s.body->setHasSelfCollision(false);
  s.world->addMultiBody(s.body.get());

  s.ball_shape = std::make_unique<btSphereShape>(static_cast<btScalar>(r));
  // Collision from primitives: the ball, and the neck as a capsule along the link's +x
  // (the component's Z) from the centre to neck_length.
  s.component_shape = std::make_unique<btCompoundShape>();
  s.component_shape->addChildShape(btTransform::getIdentity(), s.ball_shape.get());
  if (g.neck_length > 0) {
    s.neck_shape = std::make_unique<btCapsuleShapeX>(static_cast<btScalar>(g.neck_radius),
                                                     static_cast<btScalar>(g.neck_length));
    btTransform at_mid = btTransform::getIdentity();
    at_mid.setOrigin(btVector3(static_cast<btScalar>(g.neck_length / 2), 0, 0));
    s.component_shape->addChildShape(at_mid, s.neck_shape.get());
  }
  s.dummy_shape = std::make_unique<btSphereShape>(kDummyRadius);
  for (int i = 0; i < n_links; ++i) {
    auto col = std::make_unique<btMultiBodyLinkCollider>(s.body.get(), i);
    col->setCollisionShape(i % 3 == 2 ? static_cast<btCollisionShape*>(s.component_shape.get())
                                      : s.dummy_shape.get());
    s.world->addCollisionObject(col.get(), kChainGroup, kEnvironmentGroup);
    s.body->getLink(i).m_collider = col.get();
    s.colliders.push_back(std::move(col));
  }
  // Preload friction: each axis resists with up to the holding torque, so the chain keeps
  // any shape until a load exceeds it, then slips (plastic bending).
  const double max_impulse = chain.holding_torque() * params.dt;
  for (int i = 0; i < n_links; ++i) {
    auto motor = std::make_unique<btMultiBodyJointMotor>(s.body.get(), i, 0.0, max_impulse);
    s.world->addMultiBodyConstraint(motor.get());
    s.motors.push_back(std::move(motor));
  }
  // Cone limit: hard limits on each bend axis give proper impulses in the two bend
  // planes; a projection after each step catches diagonal bends (Impl::project_onto_cone).
  for (int k = 0; k < g.count; ++k) {
    for (int a = 0; a < 2; ++a) {
      auto limit = std::make_unique<btMultiBodyJointLimitConstraint>(
          s.body.get(), 3 * k + a, static_cast<btScalar>(-chain.cone_limit),
          static_cast<btScalar>(chain.cone_limit));
      s.world->addMultiBodyConstraint(limit.get());
      s.limits.push_back(std::move(limit));
    }
  }
  set_base_pose(X_WB);
}

World::~World() = default;

void World::set_base_pose(const Eigen::Isometry3d& X_WB) {
  Impl& s = *impl_;
  const Eigen::Quaterniond q_WB(X_WB.rotation());
  s.body->setBasePos(bt(X_WB.translation()));
  // Bullet stores the rotation from world to base.
  s.body->setWorldToBaseRot(
      btQuaternion(static_cast<btScalar>(q_WB.x()), static_cast<btScalar>(q_WB.y()),
                   static_cast<btScalar>(q_WB.z()), static_cast<btScalar>(q_WB.w()))
          .inverse());
  btAlignedObjectArray<btQuaternion> scratch_q;
  btAlignedObjectArray<btVector3> scratch_m;
  s.body->updateCollisionObjectWorldTransforms(scratch_q, scratch_m);
}

void PusherParams::validate() const { fields::check(*this, "pusher"); }

void ObstacleParams::validate() const {
  fields::check(*this, "obstacle");
  if (!(half_extents.minCoeff() > 0))
    fields::fail("obstacle", "half_extents_m", half_extents.minCoeff(), "must all be > 0");
}

void ForceAction::validate(int component_count) const {
  fields::check(*this, "force");
  if (component >= component_count)
    fields::fail("force", "component", component,
                 "must be < the chain's count (" + std::to_string(component_count) + ")");
  if (!(t_end >= t_start))
    fields::fail("force", "t_end_s", t_end, "must be >= t_start_s (" + format_shortest(t_start) + ")");
}

void World::set_base_trajectory(const BaseTrajectory& trajectory) {
  impl_->trajectory = trajectory;
  impl_->has_trajectory = true;
  set_base_pose(trajectory.pose(time()));
}

void World::add_pusher(const PusherParams& pusher) {
  pusher.validate();
  Impl& s = *impl_;
  Impl::Kinematic k;
  if (pusher.length > 0) {
    k.shape = std::make_unique<btCapsuleShapeZ>(static_cast<btScalar>(pusher.radius),
                                                static_cast<btScalar>(pusher.length));
  } else {
    k.shape = std::make_unique<btSphereShape>(static_cast<btScalar>(pusher.radius));
  }
  k.path = pusher.path;
  k.motion = std::make_unique<btDefaultMotionState>(bt(pusher.path.pose(time())));
  k.body = std::make_unique<btRigidBody>(0.0f, k.motion.get(), k.shape.get());
  k.body->setCollisionFlags(k.body->getCollisionFlags() | btCollisionObject::CF_KINEMATIC_OBJECT);
  k.body->setActivationState(DISABLE_DEACTIVATION);
  s.world->addRigidBody(k.body.get(), kEnvironmentGroup, kChainGroup);
  s.environment.push_back(std::move(k));
}

void World::add_obstacle(const ObstacleParams& obstacle) {
  obstacle.validate();
  Impl& s = *impl_;
  Impl::Kinematic k;
  k.shape = std::make_unique<btBoxShape>(bt(obstacle.half_extents));
  k.motion = std::make_unique<btDefaultMotionState>(bt(obstacle.X_WO));
  k.body = std::make_unique<btRigidBody>(0.0f, k.motion.get(), k.shape.get());
  s.world->addRigidBody(k.body.get(), kEnvironmentGroup, kChainGroup);
  s.environment.push_back(std::move(k));
}

void World::Impl::project_onto_cone() {
  for (int k = 0; k < chain.geometry.count; ++k) {
    const double a = body->getJointPos(3 * k), b = body->getJointPos(3 * k + 1);
    if (bend_angle(a, b) <= chain.cone_limit) continue;
    // Shrink both bend angles by one factor until the bend is on the cone.
    double lo = 0.0, hi = 1.0;
    for (int it = 0; it < 40; ++it) {
      const double mid = 0.5 * (lo + hi);
      (bend_angle(mid * a, mid * b) <= chain.cone_limit ? lo : hi) = mid;
    }
    body->setJointPos(3 * k, static_cast<btScalar>(lo * a));
    body->setJointPos(3 * k + 1, static_cast<btScalar>(lo * b));
    body->setJointVel(3 * k, 0);
    body->setJointVel(3 * k + 1, 0);
  }
}

double World::max_bend() const {
  const Impl& s = *impl_;
  double worst = 0.0;
  for (int k = 0; k < s.chain.geometry.count; ++k) {
    worst = std::max(worst, bend_angle(s.body->getJointPos(3 * k), s.body->getJointPos(3 * k + 1)));
  }
  return worst;
}

void World::add_gravity_switch(const GravityAction& action) {
  if (!std::isfinite(action.t)) throw std::invalid_argument("GravityAction.t: must be finite");
  impl_->gravity_switches.push_back(action);
}

void World::add_force(const ForceAction& action) {
  action.validate(impl_->chain.geometry.count);
  impl_->actions.push_back(action);
}

void World::step() {
  Impl& s = *impl_;
  const double t = time();
  const double t_next = t + s.params.dt;
  for (const GravityAction& gs : s.gravity_switches) {
    // Switches take effect in the step that contains their time.
    if (gs.t >= t && gs.t < t_next) {
      s.world->setGravity(btVector3(0, 0, gs.on ? -static_cast<btScalar>(s.params.g) : 0));
    }
  }
  for (const ForceAction& a : s.actions) {
    if (t >= a.t_start && t < a.t_end) {
      s.body->addLinkForce(3 * a.component + 2, bt(a.force_W));
      s.body->addLinkTorque(3 * a.component + 2, bt(a.torque_W));
    }
  }
  if (s.has_trajectory) {
    const Eigen::Isometry3d X0 = s.trajectory.pose(t), X1 = s.trajectory.pose(t_next);
    set_base_pose(X1);
    s.body->setBaseVel(bt(Eigen::Vector3d((X1.translation() - X0.translation()) / s.params.dt)));
    const Eigen::AngleAxisd dR(X1.linear() * X0.linear().transpose());
    s.body->setBaseOmega(bt(Eigen::Vector3d(dR.axis() * dR.angle() / s.params.dt)));
  }
  for (auto& e : s.environment) {
    if (!e.path.empty()) e.motion->setWorldTransform(bt(e.path.pose(t_next)));
  }
  s.world->stepSimulation(static_cast<btScalar>(s.params.dt), 0,
                          static_cast<btScalar>(s.params.dt));
  s.project_onto_cone();
  ++s.steps;
}

void World::step_until(double t) {
  while (time() + 0.5 * impl_->params.dt < t) step();
}

double World::time() const { return static_cast<double>(impl_->steps) * impl_->params.dt; }

Truth World::truth() const {
  const Impl& s = *impl_;
  const ComponentGeometry& g = s.chain.geometry;
  Truth out;
  out.t = time();
  // The component frame K of the paper: Z along the chain (the link's +x), X = link y.
  Eigen::Matrix3d R_LK;
  R_LK.col(0) = Eigen::Vector3d::UnitY();
  R_LK.col(1) = Eigen::Vector3d::UnitZ();
  R_LK.col(2) = Eigen::Vector3d::UnitX();
  for (int k = 0; k < g.count; ++k) {
    const int i = 3 * k + 2;
    const btVector3 p = s.body->localPosToWorld(i, btVector3(0, 0, 0));
    const btMatrix3x3 R = s.body->localFrameToWorld(i, btMatrix3x3::getIdentity());
    Eigen::Matrix3d R_WL;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) R_WL(r, c) = R[r][c];
    }
    Eigen::Isometry3d X_WK = Eigen::Isometry3d::Identity();
    X_WK.linear() = R_WL * R_LK;
    X_WK.translation() = eig(p);
    out.X_WK.push_back(X_WK);
    out.nodes_W.push_back(eig(p));
  }
  {
    const btQuaternion q = s.body->getWorldToBaseRot().inverse();
    out.X_WB.linear() = Eigen::Quaterniond(q.w(), q.x(), q.y(), q.z()).toRotationMatrix();
    out.X_WB.translation() = eig(s.body->getBasePos());
  }
  // Tip point p_M: one pitch beyond the last ball along its axis (Eq. 1).
  out.nodes_W.push_back(out.X_WK.back() * Eigen::Vector3d(0, 0, g.pitch));
  for (int i = 0; i < s.links(); ++i) out.joint_angles.push_back(s.body->getJointPos(i));
  const int manifolds = s.dispatcher->getNumManifolds();
  for (int i = 0; i < manifolds && !out.contact; ++i) {
    const btPersistentManifold* mf = s.dispatcher->getManifoldByIndexInternal(i);
    for (int c = 0; c < mf->getNumContacts(); ++c) {
      if (mf->getContactPoint(c).getDistance() <= 0.0) out.contact = true;
    }
  }
  return out;
}

}  // namespace linksight::sim
