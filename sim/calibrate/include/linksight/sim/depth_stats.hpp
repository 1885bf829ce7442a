#pragma once
/// @file Statistics of a depth camera's noise and artefacts, measured on depth images of
/// any static or slowly moving scene: plane-fit sigma by depth and by incidence angle,
/// the spatial correlation of the residuals, invalid bands and flying pixels at depth
/// discontinuities (per side), the projector baseline and side from the shadow widths,
/// interior holes and the quantization step. The same numbers come out of a real recording
/// and of a simulated one (`linksight render`), which is what `calibrate-noise` fits the
/// noise model to and what `fidelity` compares. Nothing here knows the scene.

#include <algorithm>
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "linksight/io/depth_png.hpp"
#include "linksight/io/intrinsics.hpp"
#include "linksight/sim/mesh.hpp"
#include "linksight/sim/noise.hpp"

namespace linksight::sim {

struct DepthStatsParams {
  int window = 15;                 ///< plane-fit window side [px]
  int min_valid = 200;             ///< valid pixels a window needs (of window^2)
  /// A window with any plane-fit residual above this holds an edge or a flying pixel,
  /// not a surface: it is left out [m].
  double max_residual = 0.01;
  double edge_jump = 0.02;  ///< depth step that makes a discontinuity [m]
  int max_band_px = 40;     ///< wider invalid runs are not an edge band [px]
  int max_hole_px = 1000;   ///< larger enclosed invalid regions are not holes [px]
  /// Depth bin edges [m] and incidence-angle bin edges [rad] for sigma.
  std::vector<double> depth_edges = {0.40, 0.50, 0.60, 0.70, 0.80, 0.90, 1.00};
  std::vector<double> angle_edges = {0.0, 0.2618, 0.5236, 0.7854, 1.0472, 1.3090, 1.5708};
  /// sigma by depth, and the residual correlation, use windows under this incidence: the
  /// angle term stays out of the one, the lateral noise's depth effect out of the other [rad].
  double depth_bin_max_angle = 0.5236;
  /// Window sides [px] at which the plane- and quadratic-fit sigma are also reported
  /// (DepthStats::scales): noise that varies slowly over tens of pixels is taken up by a
  /// quadratic in a large window, not in a small one.
  std::vector<int> scale_windows = {9, 15, 25};
  /// Valid neighbours (a row's or a column's) farther apart in depth than this make a
  /// jump (DepthStats::neighbour_jumps) [m].
  double neighbour_jump = 0.02;
  void validate() const;  ///< throws std::invalid_argument naming the field
};

/// Lags of the directional residual correlation (DepthStats::correlation_rows).
inline constexpr int kCorrelationLags = 6;

/// A quadratic's sigma "clearly below" a plane's (DepthStats::quad_beats_plane): under this
/// fraction of it.
inline constexpr double kQuadBeatsPlane = 0.8;

/// Median plane-fit sigma of the windows in one bin.
struct SigmaBin {
  double lo = 0, hi = 0;  ///< bin edges (m or rad)
  int windows = 0;
  double sigma = 0;       ///< median [m]; 0 when no window
  double centre = 0;      ///< median depth [m] or angle [rad] of its windows
};

/// Depth discontinuities seen with the near surface on one side of the gap, scanning rows.
struct EdgeSide {
  int edges = 0;           ///< discontinuities > edge_jump with a valid, stable pixel each side
  int direct = 0;          ///< of them, valid pixel next to valid pixel across the jump
  /// Fractions of edges whose first (second) pixel past the near surface's last stable
  /// pixel, toward the far side, is invalid.
  double invalid_1px = 0;
  double invalid_2px = 0;
  double band_median_px = 0;  ///< median invalid run width [px]
  /// Least-squares fit band_px = slope * f (1/z_near - 1/z_far) + intercept: slope is the
  /// projector baseline [m] when this is the shadow side.
  double slope = 0, intercept = 0;
  double fit_r = 0;        ///< correlation of the fit
  /// Every edge: f (1/z_near - 1/z_far) [px] and the band width between the stable sides
  /// [px], for figures.
  std::vector<double> gap_px, width_px;
};

struct DepthStats {
  int frames = 0;
  int window = 15;  ///< the plane-fit window side the statistics used [px]
  double depth_bin_max_angle = 0;  ///< the angle limit of sigma_by_depth's windows [rad]
  long valid_px = 0;
  double depth_step = 0;  ///< quantization step of the raw values [m]
  std::vector<SigmaBin> sigma_by_depth, sigma_by_angle;
  int windows = 0;        ///< accepted plane-fit windows
  /// Every accepted window: median depth [m], incidence of its fitted plane [rad], sigma
  /// of the residuals of the plane fit (3 parameters) and of a quadratic surface's (6) [m].
  struct Window {
    double z = 0, angle = 0, sigma = 0, sigma_quad = 0;
  };
  std::vector<Window> samples;
  /// Residual correlation at lags 1..4 px (horizontal and vertical pooled), over windows
  /// under depth_bin_max_angle, on the residuals of a quadratic surface.
  std::array<double, 4> correlation{};
  /// The same correlation along rows only (lag in u) and along columns only (lag in v), at
  /// lags 1..kCorrelationLags px: real cameras' noise is not isotropic.
  std::array<double, kCorrelationLags> correlation_rows{}, correlation_cols{};
  /// correlation_rows and correlation_cols per depth bin (DepthStatsParams::depth_edges)
  /// of the windows' median depth, over the windows they read: whether the noise's
  /// correlation changes with depth (docs/sensor.md, "Not depth: the rows' correlation by
  /// depth"). Reported, not fitted.
  struct CorrelationBin {
    double lo = 0, hi = 0;  ///< bin edges [m]
    int windows = 0;        ///< windows under depth_bin_max_angle in the bin
    std::array<double, kCorrelationLags> rows{}, cols{};  ///< 0 where a lag has no pair
  };
  std::vector<CorrelationBin> correlation_by_depth;
  /// Median quadratic-fit sigma per incidence bin (the bins of sigma_by_angle).
  std::vector<SigmaBin> sigma_quad_by_angle;
  /// Median quadratic-fit sigma per depth bin, of the windows sigma_by_depth reads (under
  /// depth_bin_max_angle): how the pixel-scale noise grows with depth.
  std::vector<SigmaBin> sigma_quad_by_depth;
  /// Share of the accepted windows whose quadratic-fit sigma is below kQuadBeatsPlane times
  /// their plane-fit sigma: how much of the noise varies over the window, not pixel to pixel.
  double quad_beats_plane = 0;
  /// Per side of params.scale_windows, over every accepted window of that side (accepted as
  /// for `window`: min_valid scaled by area, no residual above max_residual).
  struct Scale {
    int window = 0;                 ///< [px]
    int windows = 0;                ///< accepted
    double sigma = 0;               ///< median plane-fit sigma [m]
    double sigma_quad = 0;          ///< median quadratic-fit sigma [m]
    double quad_beats_plane = 0;    ///< as the field of that name
  };
  std::vector<Scale> scales;
  /// Pairs of valid pixels next to each other in a row or a column, and those of them
  /// more than params.neighbour_jump apart in depth (a real camera leaves a discontinuity
  /// invalid; per million pairs: neighbour_jumps * 1e6 / neighbour_pairs).
  long neighbour_pairs = 0, neighbour_jumps = 0;
  double neighbour_jump = 0;  ///< the params.neighbour_jump they were counted with [m]
  /// near_left: the near surface left of the gap (its right edge); near_right: the other.
  EdgeSide near_left, near_right;
  /// Projector: which side the shadows show it on, and the baseline along the camera's
  /// x axis from the shadow side's fit [m], signed as NoiseParams (negative: image-left).
  int projector_side = 0;  ///< +1 image-right, -1 image-left, 0 undecided
  double baseline = 0;
  /// Flying pixels: valid pixels next to an edge band lying between the two sides (more
  /// than 10% of the gap from both); their share of the valid pixels next to bands, and
  /// the median of (z - z_near) / (z_far - z_near).
  double flying_rate = 0;
  double flying_position = 0;
  double flying_iqr = 0;         ///< interquartile range of that position
  long band_neighbours = 0;
  long flying = 0;               ///< flying pixels counted
  /// Flying pixels counted beside the bands, which counts the same on the camera and on
  /// the model however many valid fragments a band holds (those enter flying_rate's
  /// denominator): per discontinuity with an invalid pixel between its stable sides, the
  /// valid pixels at most 2 px before or after each run of invalid pixels there (from the
  /// stable sides' outer neighbours on; each pixel once), and of them those 10-90% across.
  long band_side_pixels = 0, band_side_flying = 0;
  double flying_band_rate = 0;  ///< band_side_flying / band_side_pixels
  /// Share of discontinuities (both sides) with one lone valid pixel in the gap, 10-90%
  /// across: a flying pixel, not a side face seen at grazing incidence.
  double flying_per_edge = 0;
  /// Interior holes: 4-connected invalid regions enclosed by valid pixels of one surface
  /// (no discontinuity around them), with nothing else invalid within 2 px.
  std::vector<int> hole_sizes;  ///< [px], every hole of every frame
  double holes_per_frame = 0;
  long pixels = 0;  ///< width x height x frames: valid_px / pixels is the valid fraction
};

/// Whether window `w` counts in `bin` of sigma by depth (`by_depth`: only windows under
/// `max_angle` [rad]) or by incidence angle.
[[nodiscard]] inline bool in_sigma_bin(const DepthStats::Window& w, const SigmaBin& bin,
                                       bool by_depth, double max_angle) {
  const double x = by_depth ? w.z : w.angle;
  return x >= bin.lo && x < bin.hi && !(by_depth && w.angle >= max_angle);
}

/// Statistics of `frames` (raw depth, 0 = invalid) with `intrinsics` (size and depth unit
/// must match). With `seen`, `frames` re-render those frames (rerender_surfaces' order:
/// image i is a draw of seen[i mod seen.size()]), and a hole (its count and its size)
/// counts only where the seen frame shows a surface: each pixel of it and within 2 px of
/// it (the ring that makes a hole isolated) valid there or in one of that frame's own
/// interior holes. The re-rendered surfaces go on over what the camera left (its bands,
/// the gaps between fingers, up to DepthSurfaceParams::max_gap_px), and the model's holes
/// on those fills have no counterpart in the camera's frame (docs/sensor.md). Throws
/// std::invalid_argument naming the problem: no frame, a frame or seen frame whose size
/// differs from the intrinsics, no valid pixel, too few flat windows to estimate sigma,
/// or a `seen` that is empty or whose size does not divide the frames'.
[[nodiscard]] DepthStats depth_stats(const std::vector<io::DepthImage>& frames,
                                     const io::Intrinsics& intrinsics,
                                     const DepthStatsParams& params = {},
                                     const std::vector<io::DepthImage>* seen = nullptr);

/// A half of a recording, for validation that is not in-sample (issue 20, part 3): fit on
/// one half, compare on the other. `even` / `odd`: the frames at even / odd positions of
/// the recording's order (0, 2, ... / 1, 3, ...); `near` / `far`: the frames sorted by
/// their median valid depth (ties by position), the first ceil(n/2) / the rest; `all`:
/// every frame. Each pair of halves splits the recording.
enum class FrameHalf { all, even, odd, near, far };
/// Every FrameHalf, in declaration order (the names' one list: parsing, CLI choices).
inline constexpr FrameHalf kFrameHalves[] = {FrameHalf::all, FrameHalf::even, FrameHalf::odd,
                                             FrameHalf::near, FrameHalf::far};
/// "all" / "even" / "odd" / "near" / "far"; parse throws std::invalid_argument naming the
/// value and the choices.
[[nodiscard]] std::string_view to_string(FrameHalf half);
[[nodiscard]] FrameHalf parse_frame_half(std::string_view name);
/// The positions (ascending) of `half`'s frames in `frames`; `intrinsics` gives the depth
/// scale. Throws std::invalid_argument when a frame has no valid pixel (`near` / `far`).
[[nodiscard]] std::vector<std::size_t> frame_half(const std::vector<io::DepthImage>& frames,
                                                  const io::Intrinsics& intrinsics,
                                                  FrameHalf half);

/// Each frame's own surface (depth_surface_mesh) rendered through the simulated camera at
/// `intrinsics` with `noise`, draws from (seed, frame index): the recording's geometry
/// with the sensor model's artefacts instead of the camera's. With NoiseParams::off()
/// (quantization kept) it measures what the surfaces' shape alone puts into the plane-fit
/// sigma. `draws` > 1 returns that many images of each frame, draw-major (image d n + f
/// is frame f's draw d, n = frames.size(); draw 0 is the one-draw result): the noise
/// model applied again to the same cast with the draws of frame index d n + f (the
/// lateral jitter, part of the cast, is drawn once per frame), so that statistics read
/// over all of them are the model's expectation rather than one draw's (a few hundred
/// flying pixels or 60 holes move 10-15% between draws). Throws as depth_surface_mesh
/// does, and std::invalid_argument for draws < 1.
[[nodiscard]] std::vector<io::DepthImage> rerender_surfaces(
    const std::vector<io::DepthImage>& frames, const io::Intrinsics& intrinsics,
    const NoiseParams& noise, std::uint64_t seed, int draws = 1,
    const DepthSurfaceParams& surface = {});
/// The seed of a comparison's draws (`fidelity --rerender`, the held-out tests): not the
/// fit's (RerenderFitParams::seed, 1), so that a comparison, in sample or held out, never
/// reads the draws a fit was tuned on (the same seed and frame keys give the same holes and
/// white noise in image coordinates, whatever the frames).
inline constexpr std::uint64_t kCompareSeed = 2;

/// What the window estimator of depth_stats reads from the unit-variance axial field of
/// `axial` (its kernel, correlation widths and low-frequency share; the sigma terms do not
/// matter), over full windows: the residual correlation at lags 1..4 pooled over both
/// directions, and along rows and along columns at lags 1..kCorrelationLags (quadratic
/// residuals, as depth_stats reads them); the plane-fit and quadratic-fit variances as
/// fractions of the true one. The fits remove low frequencies, so all read lower than the
/// noise itself; fit_noise inverts this.
struct WindowResponse {
  std::array<double, 4> correlation{};
  std::array<double, kCorrelationLags> correlation_rows{}, correlation_cols{};
  double variance_factor = 1;       ///< plane fit (DepthStats::Window::sigma)
  double quad_variance_factor = 1;  ///< quadratic fit (DepthStats::Window::sigma_quad)
};
/// Throws std::invalid_argument unless window >= 5, fields::FieldError when a field of
/// `axial` is out of the scene's range.
[[nodiscard]] WindowResponse window_response(const AxialNoise& axial, int window = 15);
/// The one-field isotropic model of width `correlation_px` (0: white).
[[nodiscard]] WindowResponse window_response(double correlation_px, int window = 15);

/// What a plane fit in windows of `window` px reads of `axial`'s noise at depth z [m] and
/// incidence theta [rad]: sigma_z times the square root of window_response's variance
/// factor; with low_angle_term false, sqrt((a + c z^2)^2 (F + (1 - s) F_pixel (r^2 - 1)) +
/// t^2 F_pixel), the angle term t read as the pixel-scale field's alone (F the two fields'
/// factor at their shares, F_pixel the pixel field's, s low_share, r
/// AxialNoise::pixel_depth_factor(z)). The low field's grid (low_stride_px) is read as the
/// Gaussian it samples [m].
class AxialReading {
 public:
  explicit AxialReading(const AxialNoise& axial, int window = 15);
  [[nodiscard]] double sigma(double z, double theta) const;

 private:
  AxialNoise axial_;
  double mix_ = 1, pixel_ = 1;  // variance factors: both fields, the pixel-scale one alone
};

/// The noise model's parameters fitted to measured statistics, and what could not be.
struct NoiseFit {
  NoiseParams params;              ///< `start` with every term the data determine replaced
  std::vector<std::string> notes;  ///< one line per term kept from `start`, and why
};

/// What fit_noise fits of the axial field's structure (AxialNoise): `one_field` the single
/// isotropic field (the sr300-one-field preset's); `two_term` a pixel-scale field with its own
/// widths along rows and columns plus a low-frequency field with its own widths and share of the
/// variance (docs/sensor.md: on the shared SR305 frames it does not yet read as the camera
/// does, so it is not the default); `matern52` one Matern-5/2 field (AxialKernel) with its
/// own ranges along rows and columns, fitted to the same readings as `two_term`;
/// `two_scale` a pixel-scale field that carries the angle term and a low-frequency field
/// of a + c z^2 only (AxialNoise::low_angle_term false), fitted by re-rendering the
/// recording (fit_noise_rerendered: it needs the frames, fit_noise alone refuses it).
enum class NoiseStructure { one_field, two_term, matern52, two_scale };
/// Every NoiseStructure, in declaration order (the names' one list: parsing, CLI choices).
inline constexpr NoiseStructure kNoiseStructures[] = {NoiseStructure::one_field, NoiseStructure::two_term,
                                                      NoiseStructure::matern52, NoiseStructure::two_scale};
/// "one-field" / "two-term" / "matern52" / "two-scale"; parse throws std::invalid_argument
/// naming the value and choices.
[[nodiscard]] std::string_view to_string(NoiseStructure structure);
[[nodiscard]] NoiseStructure parse_noise_structure(std::string_view name);

/// Fits the model to `stats`:
/// - the structure (`two_term`): the two fields' widths and the low field's share whose
///   window_response (at stats.window) reads, in least squares, the measured correlation
///   along rows and along columns at lags 1..4 and the ratio of the quadratic fit's
///   variance to the plane fit's (with `shape`'s taken out of it); `matern52`: the one
///   Matern-5/2 field's ranges (3-20 px) against the same readings; `one_field`: the one
///   isotropic Gaussian width that matches the lag-1 correlation (pooled). The result's
///   kernel is the structure's, whatever `start`'s. With it the plane-fit sigma is
///   corrected to the noise's own;
/// - axial a, c, k_theta jointly, non-negative, minimizing the largest relative error
///   over the depth bins and the angle bins with 10 windows or more (what a comparison
///   with the camera sees), each bin's model its median over the bin's windows;
/// - the projector baseline, signed, when the shadows decide a side;
/// - the edge band on the side away from the shadow (band_p1, band_p2 given start's
///   p_drop); the flying pixels' position and spread (median and interquartile range),
///   and p_flying from the flying pixels per discontinuity given p_drop;
/// - the hole rate (holes per frame over the valid fraction of the image: a hole only
///   shows on a surface) and the median and 90th percentile of hole sizes.
/// With `shape` (the statistics of the recording's surfaces re-rendered without noise,
/// rerender_surfaces), each bin's sigma is first corrected for what the surfaces' shape
/// puts into a plane fit: sqrt(sigma^2 - shape^2), since the camera's noise and the
/// shape's residual add in quadrature (at least a tenth of sigma is kept).
/// Every term kept from `start`, and every measurement the model cannot follow, gets a note.
/// Throws std::invalid_argument for `two_scale` (fit_noise_rerendered fits it).
[[nodiscard]] NoiseFit fit_noise(const DepthStats& stats, const NoiseParams& start,
                                 const DepthStats* shape = nullptr,
                                 NoiseStructure structure = NoiseStructure::one_field);

/// One statistic target_mismatch compared (its name, and the two readings in the
/// statistic's own unit: metres, a share, a count per frame, pixels).
struct TargetStatistic {
  std::string name;
  double real = 0, sim = 0;
  /// Compared as sim - real (a correlation the camera reads under kSmallCorrelation in
  /// magnitude), else as sim / real (the camera's reading is then > 0).
  bool difference = false;
  double e = 0;  ///< its error: 1 at the band's edge
  /// An edge statistic's image sides, read off the projector side (-1 left, +1 right):
  /// 3 real's + the simulation's; 0 for every other statistic.
  int sides = 0;
  /// sim - real or sim / real, as it is compared.
  [[nodiscard]] double value() const { return difference ? sim - real : sim / real; }
};

/// How far a simulated recording's statistics `sim` are from the camera's `real` on the
/// targets of issue 20 (docs/sensor.md). Each statistic's error e is |ln(sim / real)| /
/// ln(1.25) (1 at the edge of the band 0.8-1.25), or, for a correlation the camera reads
/// under kSmallCorrelation in magnitude, |sim - real| / kSmallCorrelationTol; `cost` sums
/// e^2 (so a fit centres every statistic in its band, rather than stopping inside it, which
/// held out leaves less at its edges) over: the plane-fit sigma per depth
/// bin and per angle bin and the quadratic-fit sigma per angle bin and per depth bin (bins with 10 windows in
/// the camera's frames; see kMinSimWindows), the correlation along rows and along columns at lags 1-4, the
/// quadratic-beats-plane share, the first and second pixel past the near surface invalid
/// and the median band width on the side away from the projector (where the camera's frames
/// decide a side; on the same image side where the simulation's do not), the flying rate
/// beside the bands and the holes per frame (where the camera has any).
struct TargetMismatch {
  double cost = 0;
  int statistics = 0;                ///< how many were compared
  /// Those with e > 1: "name sim/real", or "name +d (sim - real)" for a difference.
  std::vector<std::string> outside;
  std::vector<TargetStatistic> compared;  ///< each of them, in the order above
};
inline constexpr double kSmallCorrelation = 0.2, kSmallCorrelationTol = 0.05;
/// A sigma bin counts (in the fits, the mismatch, the two-scale fit's depth range and the
/// held-out checks) where the camera's frames hold this many windows.
inline constexpr int kMinBinWindows = 10;
/// The simulation's reading of a bin that counts is its median from this many windows, and
/// under it the bin counts as read 0 (a model must not lower its cost by losing the
/// windows that would measure it).
inline constexpr int kMinSimWindows = 5;
[[nodiscard]] TargetMismatch target_mismatch(const DepthStats& real, const DepthStats& sim);

/// A statistic of target_mismatch on all frames, and how much it rests on any one frame.
struct TargetSpread {
  TargetStatistic all;  ///< on every frame (and every draw)
  /// The jackknife's standard error of all.value(): sqrt((g - 1) / g sum_i (v_i -
  /// v_mean)^2), v_i its value without group i of the frames on either side (and without
  /// every draw of them); g groups of consecutive frames, one frame each up to
  /// `max_groups` frames (target_jackknife). It says how far the same camera and model, seen on other
  /// frames of the same kind, would move the figure; not how far the model's own fit
  /// would. For a median of whole pixels it is the jump between neighbouring values more
  /// than an error. NaN where leaving a group out leaves the statistic uncompared or
  /// compared otherwise: a bin under kMinBinWindows windows, a correlation whose magnitude
  /// crosses kSmallCorrelation, an edge statistic whose projector side changes, or a
  /// group without which the statistics cannot be read at all.
  double se = 0;
};
/// target_jackknife's groups at most, by default: its cost is that many readings of
/// nearly all the frames.
inline constexpr int kJackknifeGroups = 20;
/// Each statistic of target_mismatch(depth_stats(real), depth_stats(sim, ..., &real))
/// (the re-render's holes counted where the camera saw a surface) with its spread
/// over the frames. `sim` holds the same frames re-rendered (rerender_surfaces), `draws`
/// images of each, draw-major: the comparison is paired, so a frame leaves both sides
/// together; g = min(frames, max_groups) groups (TargetSpread::se). Throws
/// std::invalid_argument for under 3 frames, max_groups under 2, or a `sim` whose size is
/// not a positive multiple of `real`'s, and as depth_stats does on all frames.
[[nodiscard]] std::vector<TargetSpread> target_jackknife(const std::vector<io::DepthImage>& real,
                                                         const std::vector<io::DepthImage>& sim,
                                                         const io::Intrinsics& intrinsics,
                                                         const DepthStatsParams& params = {},
                                                         int max_groups = kJackknifeGroups);

/// The statistics of the camera's frames and of their re-renders without one group of
/// frames (and every draw of them): what target_jackknife reads, for any statistic.
struct LeftOut {
  DepthStats real, sim;
};
/// For each of target_jackknife's g groups in turn, the frames without it read as
/// target_jackknife reads them (the re-render's holes where the camera saw a surface);
/// nullopt where they cannot be read. Throws as target_jackknife.
[[nodiscard]] std::vector<std::optional<LeftOut>> leave_groups_out(
    const std::vector<io::DepthImage>& real, const std::vector<io::DepthImage>& sim,
    const io::Intrinsics& intrinsics, const DepthStatsParams& params = {},
    int max_groups = kJackknifeGroups);
/// target_jackknife from readings made already: `real` and `sim` on every frame, `left`
/// from leave_groups_out of the same frames.
[[nodiscard]] std::vector<TargetSpread> target_jackknife(
    const DepthStats& real, const DepthStats& sim, const std::vector<std::optional<LeftOut>>& left);
/// The jackknife's standard error of a statistic read without each of g groups in turn,
/// sqrt((g - 1) / g sum_i (v_i - v_mean)^2) (TargetSpread::se); NaN when a reading is NaN
/// (not read without that group) or there are fewer than 2.
[[nodiscard]] double jackknife_se(const std::vector<double>& left);

/// How fit_noise_rerendered searches.
struct RerenderFitParams {
  int sweeps = 12;         ///< pattern-search sweeps (at most 2 renders per parameter: 20)
  std::uint64_t seed = 1;  ///< of the renders' noise draws
  /// Noise draws per frame that each candidate is read over, pooled (rerender_surfaces'
  /// draws): the search then follows the model's expected statistics, not one draw's.
  int draws = 4;
  int threads = 0;         ///< OpenMP threads of each render (0: the default); any gives the same fit
  /// The lateral jitter the frames are cast with and the fit keeps [px]
  /// (LateralNoise::sigma_px, switched on; 0: none); unset, the start's (sr300-one-field's
  /// 0.1 px estimate). Not searched: each value needs its own casts. On the shared frames
  /// the noise-free re-render reads a quadratic-fit sigma at 0-15 deg of 0.080 mm with
  /// 0.1 px and 0.045 mm with none, the camera 0.161 mm (docs/sensor.md, "The lateral
  /// jitter in the re-render").
  std::optional<double> lateral_sigma_px;
  /// Throws std::invalid_argument naming the field: sweeps < 0, draws < 1, or a
  /// lateral_sigma_px that LateralNoise refuses (through NoiseParams::validate).
  void validate() const;
};
/// The `two_scale` structure fitted to a recording by simulation: `frames` (with their
/// statistics `stats`, and `shape`, as for fit_noise) are first fitted with the one-field
/// model (fit_noise), then each frame's surface is cast once (depth_surface_mesh, that
/// fit's projector and lateral jitter, or params.lateral_sigma_px) and a pattern search over the axial a and c (one
/// scale), k_theta, the pixel-scale field's widths along rows and columns,
/// the low field's widths and share (on a 2 px grid), the pixel-scale field's depth power
/// (AxialNoise::pixel_depth_power, about 0.65 m and held to the depth bins where `stats`
/// has 10 windows), the angle term's power (AxialNoise::angle_power, with k_theta's scale
/// read at 60 degrees), dropouts.max_incidence and the hole rate (a scale) re-applies the
/// noise model to the casts and minimizes
/// target_mismatch(stats, their statistics), read with `frames` as depth_stats' `seen`
/// (so `stats` is expected to be depth_stats(frames)). Everything else is the one-field
/// fit's. Deterministic: the same frames and params give the same fit for any thread
/// count. The notes add the start, the final cost and what stays outside the band. Throws
/// as fit_noise and depth_surface_mesh do, and std::invalid_argument for `params` that
/// RerenderFitParams::validate refuses.
[[nodiscard]] NoiseFit fit_noise_rerendered(const std::vector<io::DepthImage>& frames,
                                            const io::Intrinsics& intrinsics,
                                            const DepthStats& stats, const DepthStats* shape,
                                            const NoiseParams& start,
                                            const RerenderFitParams& params = {});

}  // namespace linksight::sim
