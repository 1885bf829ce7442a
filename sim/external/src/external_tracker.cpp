#include "linksight/sim/external_tracker.hpp"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <vector>

#include <nlohmann/json.hpp>

#include "linksight/io/chain_json.hpp"
#include "linksight/io/json_input.hpp"
#include "linksight/tracker/backend.hpp"
#include "linksight/tracker/format.hpp"
#include "linksight/tracker/mode.hpp"

extern char** environ;

namespace linksight::sim {
namespace {

using Clock = std::chrono::steady_clock;

double now_s() { return std::chrono::duration<double>(Clock::now().time_since_epoch()).count(); }

// Milliseconds left to `deadline` for poll(), at least 0.
int ms_left(double deadline) {
  const double left = deadline - now_s();
  return left <= 0 ? 0 : static_cast<int>(std::min(left * 1e3 + 1, 2e9));
}

// An answer longer than this is not a frame's nodes: the framing is lost (limits.hpp).
constexpr std::size_t kMaxAnswer = kMaxAnswerBytes;
// What an error quotes of the tracker's stderr, and of an answer that is not JSON.
constexpr int kStderrLines = 8;
constexpr std::size_t kStderrLineBytes = 200;
// What an error shows of the tracker's command: the user's own, and often a long path.
constexpr std::size_t kCommandBytes = 400;
constexpr std::size_t kQuote = 80;

std::string quote_answer(const std::string& s) {
  std::string q = "'";
  q += io::echo(s, kQuote);
  q += '\'';
  return q;
}

// SIGPIPE blocked on this thread while it writes (a closed pipe is then EPIPE, not the
// end of the harness), and a SIGPIPE left pending by such a write consumed.
class NoSigpipe {
 public:
  NoSigpipe() {
    sigemptyset(&set_);
    sigaddset(&set_, SIGPIPE);
    pthread_sigmask(SIG_BLOCK, &set_, &old_);
  }
  ~NoSigpipe() {
    const timespec zero{0, 0};
    while (sigtimedwait(&set_, nullptr, &zero) > 0) {
    }
    pthread_sigmask(SIG_SETMASK, &old_, nullptr);
  }
  NoSigpipe(const NoSigpipe&) = delete;
  NoSigpipe& operator=(const NoSigpipe&) = delete;

 private:
  sigset_t set_{}, old_{};
};


}  // namespace

void ExternalParams::validate() const { fields::check(*this, "external"); }

ExternalTrackerSpec parse_external_tracker(const std::string& text, const std::string& flag) {
  const std::size_t eq = text.find('=');
  if (eq == std::string::npos || eq + 1 == text.size())
    throw std::invalid_argument(flag + " '" + text + "': expected NAME=COMMAND");
  const std::string name = text.substr(0, eq);
  bool ok = !name.empty() && name.size() <= 40 && name != "truth";
  for (const char c : name)
    ok = ok && (std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.');
  if (!ok)
    throw std::invalid_argument(flag + " '" + text + "': the name '" + name +
                                "' must be 1-40 letters, digits, '-', '_' or '.', not 'truth'");
  for (const TrackerMode m : all_modes())
    if (to_string(m) == name)
      throw std::invalid_argument(flag + " '" + text + "': '" + name +
                                  "' is a built-in mode's name; call it something else");
  return {name, text.substr(eq + 1)};
}

namespace {

// A file descriptor closed when it goes out of scope, unless released.
struct Fd {
  int fd = -1;
  Fd() = default;
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  ~Fd() {
    if (fd >= 0) close(fd);
  }
  int release() {
    const int f = fd;
    fd = -1;
    return f;
  }
};

// How `status` ended the shell that ran the command. A shell reports its command's death
// by signal n as exit status 128 + n.
std::string exit_status(int status) {
  if (WIFEXITED(status)) {
    const int code = WEXITSTATUS(status);
    std::string out = "exited with status " + std::to_string(code);
    if (code > 128 && code <= 128 + 64)
      out += std::string(", the shell's code for its command killed by signal ") +
             std::to_string(code - 128) + " (" + strsignal(code - 128) + ")";
    return out;
  }
  if (WIFSIGNALED(status))
    return std::string("was killed by signal ") + std::to_string(WTERMSIG(status)) + " (" +
           strsignal(WTERMSIG(status)) + ")";
  return "stopped";
}

// The slice a wait looks at the cancel flag and the process in.
constexpr int kSliceMs = 50;

// The answer already parsed as JSON (defined with parse_external_answer).
ExternalAnswer answer_from_json(const nlohmann::json& a, const std::string& line,
                                long long frame_index, int n_nodes);
}  // namespace

ExternalTracker::ExternalTracker(ExternalTrackerSpec spec, const ExternalParams& params,
                                 int nodes, const io::Intrinsics& K,
                                 const ComponentGeometry& geometry, const BasePriorParams& prior)
    : spec_(std::move(spec)), params_(params), nodes_(nodes), K_(K), geometry_(geometry),
      prior_(prior) {
  params_.validate();
  if (nodes_ < 1) throw std::invalid_argument("external tracker: nodes must be >= 1");
  const std::string who = "external tracker '" + io::echo(spec_.name) + "' (" +
                          io::echo(spec_.command, kCommandBytes) + "): ";
  // Its stderr goes to a file (a pipe nobody drained could stall it), quoted on failure;
  // unlinked at once, so that nothing is left behind however linksight ends.
  const char* tmpdir = std::getenv("TMPDIR");
  std::string tmpl = std::string(tmpdir && *tmpdir ? tmpdir : "/tmp") + "/linksight-tracker-XXXXXX";
  Fd err, in_r, in_w, out_r, out_w;
  err.fd = mkostemp(tmpl.data(), O_CLOEXEC);
  if (err.fd < 0)
    throw ExternalTrackerError(who + "cannot create a file for its stderr in " + tmpl + ": " +
                               std::strerror(errno));
  unlink(tmpl.c_str());
  int p[2];
  if (pipe2(p, O_CLOEXEC) != 0)
    throw ExternalTrackerError(who + "cannot create a pipe: " + std::strerror(errno));
  in_r.fd = p[0];
  in_w.fd = p[1];
  if (pipe2(p, O_CLOEXEC) != 0)
    throw ExternalTrackerError(who + "cannot create a pipe: " + std::strerror(errno));
  out_r.fd = p[0];
  out_w.fd = p[1];
  posix_spawn_file_actions_t fa;
  posix_spawnattr_t attr;
  if (posix_spawn_file_actions_init(&fa) != 0)
    throw ExternalTrackerError(who + "cannot be started: out of memory");
  if (posix_spawnattr_init(&attr) != 0) {
    posix_spawn_file_actions_destroy(&fa);
    throw ExternalTrackerError(who + "cannot be started: out of memory");
  }
  posix_spawn_file_actions_adddup2(&fa, in_r.fd, 0);
  posix_spawn_file_actions_adddup2(&fa, out_w.fd, 1);
  posix_spawn_file_actions_adddup2(&fa, err.fd, 2);
  // Its own process group: a Ctrl-C at the terminal reaches the harness, which ends the
  // episode and then the tracker (all of its group), not the tracker in mid-frame.
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETPGROUP | POSIX_SPAWN_SETSIGMASK |
                                      POSIX_SPAWN_SETSIGDEF);
  posix_spawnattr_setpgroup(&attr, 0);
  sigset_t none, all;
  sigemptyset(&none);
  sigfillset(&all);
  posix_spawnattr_setsigmask(&attr, &none);
  posix_spawnattr_setsigdefault(&attr, &all);
  std::string command = spec_.command;
  char sh[] = "/bin/sh", dash_c[] = "-c";
  char* argv[] = {sh, dash_c, command.data(), nullptr};
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, "/bin/sh", &fa, &attr, argv, environ);
  posix_spawn_file_actions_destroy(&fa);
  posix_spawnattr_destroy(&attr);
  if (rc != 0) throw ExternalTrackerError(who + "cannot be started: " + std::strerror(rc));
  pid_ = pgid_ = pid;
  to_child_ = in_w.release();
  from_child_ = out_r.release();
  stderr_fd_ = err.release();
  fcntl(to_child_, F_SETFL, fcntl(to_child_, F_GETFL) | O_NONBLOCK);
  fcntl(from_child_, F_SETFL, fcntl(from_child_, F_GETFL) | O_NONBLOCK);
}

ExternalTracker::~ExternalTracker() { stop(); }

void ExternalTracker::stop() {
  if (to_child_ >= 0) close(to_child_);  // EOF: the episode is over
  to_child_ = -1;
  if (pid_ > 0) {
    int status = 0;
    const double deadline = now_s() + 2.0;
    pid_t r = 0;
    while ((r = waitpid(pid_, &status, WNOHANG)) == 0 && now_s() < deadline) usleep(5000);
    if (r == 0) {
      kill(-pgid_, SIGKILL);
      kill(pid_, SIGKILL);
      while (waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
      }
    }
    pid_ = -1;
  }
  // Whatever it started and left running (a background job of the command) goes too.
  if (pgid_ > 0) kill(-pgid_, SIGKILL);
  pgid_ = -1;
  if (from_child_ >= 0) close(from_child_);
  from_child_ = -1;
  if (stderr_fd_ >= 0) close(stderr_fd_);
  stderr_fd_ = -1;
}

std::string ExternalTracker::stderr_tail() const {
  // The last 64 KiB at most, whatever it wrote.
  constexpr off_t kTail = 65536;
  struct stat st {};
  if (stderr_fd_ < 0 || fstat(stderr_fd_, &st) != 0) return "";
  const off_t from = st.st_size > kTail ? st.st_size - kTail : 0;
  std::string text(static_cast<std::size_t>(st.st_size - from), '\0');
  const ssize_t got = pread(stderr_fd_, text.data(), text.size(), from);
  text.resize(got > 0 ? static_cast<std::size_t>(got) : 0);
  std::vector<std::string> lines;
  std::stringstream ss(text);
  for (std::string l; std::getline(ss, l);) {
    lines.push_back(io::echo(l, kStderrLineBytes));
    if (lines.size() > kStderrLines) lines.erase(lines.begin());
  }
  if (lines.empty()) return "; its stderr is empty";
  // One line, as every message (io::printable_line): its lines joined by " | ".
  std::string out = "; its stderr ends: ";
  for (std::size_t k = 0; k < lines.size(); ++k) out += (k ? " | " : "") + lines[k];
  return out;
}

void ExternalTracker::fail(int frame, const std::string& what, double wait_s) {
  // Reap first (waiting up to wait_s for it to end), so that the message says how it ended.
  std::string how = what;
  const double deadline = now_s() + wait_s;
  while (pid_ > 0) {
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {
      how += " (it " + exit_status(status) + ")";
      pid_ = -1;
    } else if (now_s() >= deadline) {
      break;
    } else {
      usleep(5000);
    }
  }
  const std::string tail = stderr_tail();
  stop();
  throw ExternalTrackerError("external tracker '" + io::echo(spec_.name) + "' (" +
                             io::echo(spec_.command, kCommandBytes) + "): frame " +
                             std::to_string(frame) + ": " + how + tail);
}

bool ExternalTracker::wait_for(int fd, short events, double deadline, int frame) {
  for (;;) {
    if (cancel_ != nullptr && cancel_->load()) {
      stop();
      throw ExternalTrackerInterrupted("external tracker '" + io::echo(spec_.name) + "': frame " +
                                       std::to_string(frame) + ": interrupted");
    }
    const int left = ms_left(deadline);
    if (left == 0) return false;
    pollfd p{fd, events, 0};
    const int r = poll(&p, 1, std::min(left, kSliceMs));
    if (r > 0) return true;
    // Its process ended while something it started still holds the pipe open.
    int status = 0;
    if (pid_ > 0 && waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      fail(frame, exit_status(status) + " before answering");
    }
  }
}

bool ExternalTracker::write_all(const char* data, std::size_t n, double deadline, int frame) {
  NoSigpipe guard;
  while (n > 0) {
    const ssize_t w = write(to_child_, data, n);
    if (w > 0) {
      data += w;
      n -= static_cast<std::size_t>(w);
      continue;
    }
    if (w < 0 && errno == EINTR) continue;
    if (w < 0 && errno != EAGAIN) return false;  // EPIPE: it closed its stdin or died
    if (!wait_for(to_child_, POLLOUT, deadline, frame))
      fail(frame, "did not read the frame within " + format_shortest(params_.timeout_s) +
                      " s (scene key external.timeout_s)");
  }
  return true;
}

std::string ExternalTracker::read_line(double deadline, int frame) {
  std::size_t eol;
  while ((eol = pending_.find('\n')) == std::string::npos) {
    if (pending_.size() > kMaxAnswer) fail(frame, "answered with a line longer than 1 MiB");
    char buf[65536];
    const ssize_t r = read(from_child_, buf, sizeof buf);
    if (r > 0) {
      pending_.append(buf, static_cast<std::size_t>(r));
      continue;
    }
    // EOF: it closed its stdout, most likely by ending; the message says how.
    if (r == 0) fail(frame, "closed its output before answering", 1.0);
    if (errno == EINTR) continue;
    if (errno != EAGAIN) fail(frame, std::string("cannot be read: ") + std::strerror(errno));
    if (!wait_for(from_child_, POLLIN, deadline, frame))
      fail(frame, "did not answer within " + format_shortest(params_.timeout_s) +
                      " s (scene key external.timeout_s)");
  }
  std::string line = pending_.substr(0, eol);
  pending_.erase(0, eol + 1);
  return line;
}

FrameResult ExternalTracker::step(const ExternalFrameInput& in) {
  if (pid_ <= 0) throw std::logic_error("external tracker: step() after it failed");
  const auto t0 = Clock::now();
  const double deadline = now_s() + params_.timeout_s;
  const Cloud& cloud = *in.cloud;
  nlohmann::json h = {{"linksight", kExternalProtocol},
                      {"frame", in.frame},
                      {"t_s", in.t},
                      {"nodes", nodes_},
                      {"points", cloud.size()}};
  if (first_) {
    h["intrinsics"] = nlohmann::json::parse(io::intrinsics_json(K_));
    h["chain"] = nlohmann::json::parse(io::chain_json(geometry_));
  }
  if (in.X_CB != nullptr) {
    nlohmann::json X = nlohmann::json::array();
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) X.push_back(in.X_CB->matrix()(r, c));
    h["base_pose"] = {{"X_CB", X},
                      {"sigma_m", prior_.sigma_m},
                      {"sigma_deg", prior_.sigma_rad * 180.0 / 3.14159265358979323846}};
  }
  const io::DepthImage* depth = params_.send_depth ? in.depth : nullptr;
  if (params_.send_depth) {
    if (depth == nullptr || depth->data.size() != static_cast<std::size_t>(depth->width) *
                                                       static_cast<std::size_t>(depth->height))
      throw std::logic_error("external tracker: send_depth without a whole depth image");
    h["depth"] = {{"width", depth->width}, {"height", depth->height}};
  }
  first_ = false;
  const std::string header = h.dump() + "\n";
  // Little-endian float32 x y z per point, then uint16 depth: the host's own layout.
  static_assert(sizeof(float) == 4 && std::endian::native == std::endian::little);
  if (!write_all(header.data(), header.size(), deadline, in.frame) ||
      !write_all(reinterpret_cast<const char*>(cloud.xyz.data()), cloud.xyz.size() * 4,
                 deadline, in.frame) ||
      (depth != nullptr &&
       !write_all(reinterpret_cast<const char*>(depth->data.data()), depth->data.size() * 2,
                  deadline, in.frame)))
    fail(in.frame, "stopped reading its input", 1.0);
  // The answer: one line. A line for an earlier frame (the rest of an answer a stray line
  // of output displaced) is passed over, so that one stray line costs one frame.
  std::string line;
  nlohmann::json a;
  bool parsed = false;
  for (;;) {
    line = read_line(deadline, in.frame);
    parsed = false;
    // Too deep a line is not parsed at all: parse_external_answer says why.
    if (io::json_too_deep_at(line) == std::string_view::npos) try {
        a = nlohmann::json::parse(line);
        parsed = true;
      } catch (const nlohmann::json::exception&) {
      }
    if (!(parsed && a.is_object())) break;
    const auto f = a.find("frame");
    if (f == a.end() || !f->is_number_integer() || f->get<long long>() >= in.frame) break;
  }

  FrameResult r;
  r.time_s = std::chrono::duration<double>(Clock::now() - t0).count();
  r.n_points = cloud.size();
  r.sdf_error = std::numeric_limits<double>::quiet_NaN();
  // Parsed once: only a line that is not JSON goes through parse_external_answer, which
  // says why.
  const ExternalAnswer answer = parsed ? answer_from_json(a, line, in.frame, nodes_)
                                       : parse_external_answer(line, in.frame, nodes_);
  lost_detail_ = answer.lost;
  r.lost = !answer.lost.empty();
  r.reinit = answer.reinit;
  if (!r.lost) r.nodes = answer.nodes;
  return r;
}

namespace {
ExternalAnswer answer_from_json(const nlohmann::json& a, const std::string& line,
                                long long frame_index, int n_nodes) {
  ExternalAnswer out;
  const auto lost = [&](const std::string& why) {
    out.lost = why;
    out.nodes.clear();
    return out;
  };
  if (!a.is_object()) return lost("the answer is not a JSON object: " + quote_answer(line));
  const auto frame = a.find("frame");
  if (frame == a.end() || !frame->is_number_integer() || frame->get<long long>() != frame_index)
    return lost("the answer is not for frame " + std::to_string(frame_index) + ": " +
                quote_answer(line));
  if (const auto l = a.find("lost"); l != a.end() && l->is_boolean() && l->get<bool>()) {
    const auto why = a.find("reason");
    return lost("the tracker says lost" +
                (why != a.end() && why->is_string() ? ": " + quote_answer(why->get<std::string>())
                                                    : std::string()));
  }
  const auto nodes = a.find("nodes");
  if (nodes == a.end() || !nodes->is_array())
    return lost("the answer has no \"nodes\" list: " + quote_answer(line));
  if (nodes->size() != static_cast<std::size_t>(n_nodes))
    return lost("the answer has " + std::to_string(nodes->size()) + " nodes, expected " +
                std::to_string(n_nodes));
  out.nodes.resize(static_cast<std::size_t>(n_nodes));
  for (std::size_t j = 0; j < nodes->size(); ++j) {
    const nlohmann::json& q = (*nodes)[j];
    if (!q.is_array() || q.size() != 3)
      return lost("node " + std::to_string(j) + " is not [x, y, z]: " + io::json_summary(q));
    for (int c = 0; c < 3; ++c) {
      if (!q[static_cast<std::size_t>(c)].is_number())
        return lost("node " + std::to_string(j) +
                    " is not [x, y, z] of numbers: " + io::json_summary(q));
      const double v = q[static_cast<std::size_t>(c)].get<double>();
      if (!std::isfinite(v) || std::abs(v) > kMaxCoordinate)
        return lost("node " + std::to_string(j) + " has a coordinate that is not a finite " +
                    "number within 100 m: " + io::json_summary(q));
      out.nodes[j][c] = v;
    }
  }
  if (const auto re = a.find("reinit"); re != a.end() && re->is_boolean() && re->get<bool>())
    out.reinit = true;
  return out;
}
}  // namespace

ExternalAnswer parse_external_answer(const std::string& line, long long frame, int nodes) {
  if (const std::size_t at = io::json_too_deep_at(line); at != std::string_view::npos) {
    ExternalAnswer out;
    out.lost = "the answer nests deeper than " + std::to_string(io::kMaxJsonDepth) +
               " levels (byte " + std::to_string(at) + "): " + quote_answer(line);
    return out;
  }
  nlohmann::json a;
  try {
    a = nlohmann::json::parse(line);
  } catch (const nlohmann::json::exception&) {
    ExternalAnswer out;
    // Python's json.dumps writes a non-finite float as a bare NaN or Infinity, which is
    // not JSON: say so, as the token may lie past what the quote shows.
    for (const char* token : {"NaN", "Infinity"})
      if (line.find(token) != std::string::npos) {
        out.lost = std::string("the answer is not JSON: it holds ") + token +
                   ", which JSON has no number for (a node must be finite): " + quote_answer(line);
        return out;
      }
    out.lost = "the answer is not JSON: " + quote_answer(line);
    return out;
  }
  return answer_from_json(a, line, frame, nodes);
}

}  // namespace linksight::sim
