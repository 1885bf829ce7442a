#pragma once
/// @file A tracker outside linksight (issue 18, part 2): a program started once per
/// episode from a command given on the command line (never from a scene, grid or
/// recording), fed one frame at a time on its stdin and answering on its stdout, as
/// docs/protocol.md specifies (version kExternalProtocol). Frames go in order and each
/// waits for its answer, so results do not depend on the tracker's timing.

#include <Eigen/Geometry>

#include <atomic>
#include <filesystem>
#include <stdexcept>
#include <memory>
#include <string>
#include <sys/types.h>

#include "linksight/io/depth_png.hpp"
#include "linksight/io/error.hpp"
#include "linksight/io/intrinsics.hpp"
#include "linksight/tracker/cloud.hpp"
#include "linksight/tracker/fields.hpp"
#include "linksight/tracker/tracker.hpp"

namespace linksight::sim {

/// The protocol's version: the `linksight` key of every frame's header.
inline constexpr int kExternalProtocol = 1;

/// A tracker as the command line names it: `--tracker NAME=COMMAND`.
struct ExternalTrackerSpec {
  std::string name;     ///< what tables and figures call it
  std::string command;  ///< run by /bin/sh -c, in the current directory
};

/// Parses "NAME=COMMAND". Throws std::invalid_argument naming `flag` and the text: a name
/// is 1-40 letters, digits, '-', '_' or '.', and may not be a built-in mode's or "truth".
[[nodiscard]] ExternalTrackerSpec parse_external_tracker(const std::string& text,
                                                         const std::string& flag = "--tracker");

/// Scene key `external`: how long an external tracker may take.
struct ExternalParams {
  /// Per frame, from the first byte sent to the answer's end (the first frame includes
  /// the program's start: an interpreter loading its libraries) [s].
  double timeout_s = 60.0;
  /// Send each frame's 16-bit depth image after its cloud (the camera's whole frame).
  bool send_depth = false;
  template <class Archive>
  void fields(Archive& ar) {
    ar("timeout_s", timeout_s, fields::in(0.01, 86400));
    ar("send_depth", send_depth);
  }
  void validate() const;  ///< throws fields::FieldError naming the key
};

/// The tracker's process died, hung past the timeout, could not be started, or broke the
/// protocol's framing: what() names the tracker, the frame and what it did, and ends with
/// the last lines of its stderr.
class ExternalTrackerError : public io::InputError {
 public:
  using io::InputError::InputError;
};

/// step() gave up waiting because the cancel flag was raised (Ctrl-C): the frame has no
/// result; the tracker's process is ended.
class ExternalTrackerInterrupted : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// One frame as the tracker is given it.
struct ExternalFrameInput {
  int frame = 0;
  double t = 0;                               ///< [s]
  const Cloud* cloud = nullptr;               ///< camera frame [m]
  const Eigen::Isometry3d* X_CB = nullptr;    ///< the base pose prior, when given
  /// The frame's depth image (intrinsics.depth_scale per unit, 0 = none); sent when
  /// ExternalParams::send_depth, and then required.
  const io::DepthImage* depth = nullptr;
};

/// What one answer line of protocol version 1 says (docs/protocol.md): the nodes [m, C],
/// or why the frame is lost (`lost` non-empty: not JSON, not an object, another frame's,
/// the tracker's own "lost", no or a wrong count of nodes, a coordinate that is not a
/// finite number within 100 m), and whether the tracker re-initialized.
struct ExternalAnswer {
  std::string lost;
  Nodes nodes;
  bool reinit = false;
};
/// Reads `line` as the answer for `frame` with `nodes` nodes. Never throws for any line.
[[nodiscard]] ExternalAnswer parse_external_answer(const std::string& line, long long frame,
                                                   int nodes);

class ExternalTracker {
 public:
  /// Starts the process. `nodes`: how many nodes an answer must give; `K` and `geometry`:
  /// the camera and the link's components, sent with the first frame; `prior`: the base
  /// prior's σ (sent with a pose).
  ExternalTracker(ExternalTrackerSpec spec, const ExternalParams& params, int nodes,
                  const io::Intrinsics& K, const ComponentGeometry& geometry,
                  const BasePriorParams& prior);
  /// Closes its stdin (the end of the episode), gives it 2 s to exit, then kills its
  /// process group; it is always reaped.
  ~ExternalTracker();
  ExternalTracker(const ExternalTracker&) = delete;
  ExternalTracker& operator=(const ExternalTracker&) = delete;

  /// Sends one frame and reads the answer. An answer that breaks the protocol while the
  /// process lives (not JSON, another frame's, a wrong node count, a coordinate that is not
  /// finite) is a lost frame with the reason in `lost_detail`; so is `"lost": true`.
  /// Throws ExternalTrackerError when the process dies, hangs or cannot be written to.
  /// time_s is the wall time from sending to the answer, the pipe included.
  FrameResult step(const ExternalFrameInput& in);
  /// While step() waits, it looks at `cancel` every 50 ms and gives up when it is set
  /// (ExternalTrackerInterrupted). Not owned; nullptr: never.
  void set_cancel(const std::atomic<bool>* cancel) { cancel_ = cancel; }
  /// Why the last frame was lost ("" when it was not).
  [[nodiscard]] const std::string& lost_detail() const { return lost_detail_; }
  [[nodiscard]] const ExternalTrackerSpec& spec() const { return spec_; }

 private:
  [[noreturn]] void fail(int frame, const std::string& what, double wait_s = 0.0);
  // Waits until `fd` is ready for `events` or the deadline passes (false), in slices that
  // look at the cancel flag and at the process: one that ended fails the frame.
  bool wait_for(int fd, short events, double deadline, int frame);
  bool write_all(const char* data, std::size_t n, double deadline, int frame);
  std::string read_line(double deadline, int frame);
  std::string stderr_tail() const;
  void stop();

  ExternalTrackerSpec spec_;
  ExternalParams params_;
  int nodes_;
  io::Intrinsics K_;
  ComponentGeometry geometry_;
  BasePriorParams prior_;
  pid_t pid_ = -1;   // the process started (a shell), until reaped
  pid_t pgid_ = -1;  // its process group: the tracker and whatever it started
  int to_child_ = -1, from_child_ = -1;
  int stderr_fd_ = -1;  // an unlinked temporary file: nothing is left on disk
  const std::atomic<bool>* cancel_ = nullptr;
  std::string pending_;  // bytes read past the last answer's newline
  std::string lost_detail_;
  bool first_ = true;
};

}  // namespace linksight::sim
