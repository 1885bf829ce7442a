#include "linksight/io/base_pose.hpp"

#include <array>
#include <charconv>
#include <cmath>
#include <iomanip>
#include <string>

#include "linksight/io/csv.hpp"
#include "linksight/io/error.hpp"

namespace linksight::io {
namespace {

constexpr std::array<const char*, 8> kColumns = {"frame", "x_m", "y_m", "z_m",
                                                 "qw",    "qx",  "qy",  "qz"};
// A quaternion this far from unit length is not a rotation written with rounding.
constexpr double kUnitTolerance = 1e-3;

}  // namespace

void write_base_pose_header(std::ostream& out) {
  for (std::size_t c = 0; c < kColumns.size(); ++c) out << (c ? "," : "") << kColumns[c];
  out << '\n';
}

void write_base_pose_row(std::ostream& out, int frame, const Eigen::Isometry3d& X_CB) {
  Eigen::Quaterniond q(X_CB.rotation());
  if (q.w() < 0) q.coeffs() = -q.coeffs();  // one of the two, for stable files
  const Eigen::Vector3d& p = X_CB.translation();
  const auto old_flags = out.flags();
  const auto old_precision = out.precision();
  out << frame << std::fixed << std::setprecision(9) << ',' << p.x() << ',' << p.y() << ','
      << p.z() << ',' << q.w() << ',' << q.x() << ',' << q.y() << ',' << q.z() << '\n';
  out.flags(old_flags);
  out.precision(old_precision);
}

std::vector<Eigen::Isometry3d> read_base_poses(const std::filesystem::path& path,
                                               std::size_t frames) {
  const std::string file = path.string();
  CsvLimits limits;
  limits.max_rows = rows_with_room(frames);  // a row per input frame
  const CsvTable t = read_csv(path, limits);
  std::array<std::size_t, kColumns.size()> at{};
  std::array<bool, kColumns.size()> found{};
  for (std::size_t h = 0; h < t.header.size(); ++h) {
    std::size_t c = 0;
    while (c < kColumns.size() && t.header[h] != kColumns[c]) ++c;
    if (c == kColumns.size())
      throw InputError(file + ":1: unknown column '" + echo(t.header[h]) +
                       "' (expected frame,x_m,y_m,z_m,qw,qx,qy,qz)");
    if (found[c]) throw InputError(file + ":1: column '" + echo(t.header[h]) + "' given twice");
    found[c] = true;
    at[c] = h;
  }
  for (std::size_t c = 0; c < kColumns.size(); ++c)
    if (!found[c]) throw InputError(file + ":1: no column '" + kColumns[c] + "'");

  std::vector<Eigen::Isometry3d> poses(frames, Eigen::Isometry3d::Identity());
  std::vector<int> line_of(frames, 0);
  for (std::size_t r = 0; r < t.rows.size(); ++r) {
    const std::vector<std::string>& row = t.rows[r];
    const std::string where = file + ":" + std::to_string(t.lines[r]) + ": ";
    const std::string& fs = row[at[0]];
    std::size_t frame = 0;
    const auto res = std::from_chars(fs.data(), fs.data() + fs.size(), frame);
    if (res.ec != std::errc() || res.ptr != fs.data() + fs.size())
      throw InputError(where + "frame '" + echo(fs) + "' is not a frame index");
    if (frame >= frames)
      throw InputError(where + "frame " + fs + " is not among the " + std::to_string(frames) +
                       " input frames");
    if (line_of[frame] != 0)
      throw InputError(where + "frame " + fs + " given twice (first on line " +
                       std::to_string(line_of[frame]) + ")");
    line_of[frame] = t.lines[r];
    std::array<double, 7> v{};
    for (std::size_t c = 1; c < kColumns.size(); ++c) {
      const std::string& s = row[at[c]];
      double x = 0;
      const auto rv = std::from_chars(s.data(), s.data() + s.size(), x);
      if (rv.ec != std::errc() || rv.ptr != s.data() + s.size() || !std::isfinite(x))
        throw InputError(where + kColumns[c] + " '" + echo(s) + "' is not a finite number");
      v[c - 1] = x;
    }
    Eigen::Quaterniond q(v[3], v[4], v[5], v[6]);
    if (std::abs(q.norm() - 1) > kUnitTolerance)
      throw InputError(where + "the quaternion (qw,qx,qy,qz) has norm " +
                       std::to_string(q.norm()) + ", not 1");
    q.normalize();
    poses[frame].linear() = q.toRotationMatrix();
    poses[frame].translation() = Eigen::Vector3d(v[0], v[1], v[2]);
  }
  for (std::size_t f = 0; f < frames; ++f)
    if (line_of[f] == 0) throw InputError(file + ": no row for frame " + std::to_string(f));
  return poses;
}

}  // namespace linksight::io
