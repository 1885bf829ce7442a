#include "linksight/io/depth_png.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace linksight::io {

void DepthToCloudOptions::validate() const {
  if (!(min_depth >= 0.0) || std::isnan(max_depth) || !(max_depth > min_depth)) {
    throw std::invalid_argument("depth range [" + std::to_string(min_depth) + ", " +
                                std::to_string(max_depth) + "]: need 0 <= min < max");
  }
  if (crop_C && crop_C->isEmpty()) throw std::invalid_argument("crop box is empty (min > max)");
}

Cloud depth_to_cloud(const DepthImage& image, const Intrinsics& k,
                     const DepthToCloudOptions& options) {
  options.validate();
  if (image.width != k.width || image.height != k.height) {
    throw std::invalid_argument("image is " + std::to_string(image.width) + "x" +
                                std::to_string(image.height) + " but intrinsics say " +
                                std::to_string(k.width) + "x" + std::to_string(k.height));
  }
  Cloud cloud;
  for (int v = 0; v < image.height; ++v) {
    for (int u = 0; u < image.width; ++u) {
      const std::uint16_t d = image.data[static_cast<std::size_t>(v) * image.width + u];
      if (d == 0) continue;
      const double z = d * k.depth_scale;
      if (z < options.min_depth || z > options.max_depth) continue;
      const Eigen::Vector3d p = k.deproject(u, v, z);
      if (options.crop_C && !options.crop_C->contains(p)) continue;
      cloud.push_back(p);
    }
  }
  return cloud;
}

}  // namespace linksight::io
