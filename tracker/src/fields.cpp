#include "linksight/tracker/fields.hpp"

namespace linksight::fields {

std::string describe(const Rule& r) {
  const bool has_lo = std::isfinite(r.lo), has_hi = std::isfinite(r.hi);
  if (has_lo && has_hi)
    return "must be in " + std::string(r.lo_open ? "(" : "[") + format_shortest(r.lo) + ", " +
           format_shortest(r.hi) + (r.hi_open ? ")" : "]");
  if (has_lo) return std::string(r.lo_open ? "must be > " : "must be >= ") + format_shortest(r.lo);
  if (has_hi) return std::string(r.hi_open ? "must be < " : "must be <= ") + format_shortest(r.hi);
  return "must be finite";
}

bool obeys(const Rule& r, double v) {
  if (!std::isfinite(v)) return false;
  const double lo = r.lo * r.scale, hi = r.hi * r.scale;
  if (r.lo_open ? !(v > lo) : !(v >= lo)) return false;
  if (r.hi_open ? !(v < hi) : !(v <= hi)) return false;
  return true;
}

namespace {
std::string message(const std::string& root, const std::string& key, const std::string& value,
                    const std::string& rule) {
  return (root.empty() ? key : root + "." + key) + " = " + value + ": " + rule;
}
}  // namespace

FieldError::FieldError(std::string key, std::string value, std::string rule, std::string root)
    : std::invalid_argument(message(root, key, value, rule)),
      key_(std::move(key)),
      value_(std::move(value)),
      rule_(std::move(rule)),
      root_(std::move(root)) {}

FieldError FieldError::within(const std::string& parent) const {
  return FieldError(parent + "." + key_, value_, rule_);
}

FieldError FieldError::rooted(const std::string& root) const {
  return FieldError(key_, value_, rule_, root);
}

void fail(const std::string& root, const std::string& key, double value,
          const std::string& rule) {
  throw FieldError(key, format_shortest(value), rule, root);
}

}  // namespace linksight::fields
