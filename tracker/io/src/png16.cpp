// Minimal 16-bit grayscale PNG writer (stored deflate blocks: no compression library),
// and the reader on top of stb_image.
#include <array>
#include <cstring>
#include <fstream>
#include <iterator>

#define STB_IMAGE_IMPLEMENTATION
#define STBI_ONLY_PNG
#define STBI_NO_STDIO
#define STBI_FAILURE_USERMSG
#include <stb/stb_image.h>

#include "linksight/io/atomic_file.hpp"
#include "linksight/io/depth_png.hpp"
#include "linksight/io/error.hpp"

namespace linksight::io {
namespace {

// A PNG's 4-byte big-endian unsigned integer (chunk lengths, IHDR's width and height).
long long be32(const unsigned char* p) {
  return (static_cast<long long>(p[0]) << 24) | (p[1] << 16) | (p[2] << 8) | p[3];
}

std::uint32_t crc32(const unsigned char* data, std::size_t n, std::uint32_t crc = 0) {
  static const auto table = [] {
    std::array<std::uint32_t, 256> t{};
    for (std::uint32_t i = 0; i < 256; ++i) {
      std::uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  crc = ~crc;
  for (std::size_t i = 0; i < n; ++i) crc = table[(crc ^ data[i]) & 0xFF] ^ (crc >> 8);
  return ~crc;
}

void put32(std::vector<unsigned char>& v, std::uint32_t x) {
  for (int s = 24; s >= 0; s -= 8) v.push_back(static_cast<unsigned char>(x >> s));
}

void chunk(std::ostream& out, const char* type, const std::vector<unsigned char>& data) {
  std::vector<unsigned char> buf;
  put32(buf, static_cast<std::uint32_t>(data.size()));
  buf.insert(buf.end(), type, type + 4);
  buf.insert(buf.end(), data.begin(), data.end());
  put32(buf, crc32(buf.data() + 4, buf.size() - 4));
  out.write(reinterpret_cast<const char*>(buf.data()), static_cast<std::streamsize>(buf.size()));
}

// The bytes a PNG's image data inflates to: per row a filter byte and its samples, per
// Adam7 pass when interlaced (PNG specification, 7.2 and 8.2).
std::uint64_t inflated_bytes(std::uint64_t w, std::uint64_t h, int bit_depth, int colour,
                             bool adam7) {
  const std::uint64_t channels = colour == 2 ? 3 : colour == 4 ? 2 : colour == 6 ? 4 : 1;
  const std::uint64_t bits = static_cast<std::uint64_t>(bit_depth) * channels;
  const auto image = [&](std::uint64_t cw, std::uint64_t ch) {
    return cw == 0 || ch == 0 ? 0 : ch * (1 + (cw * bits + 7) / 8);
  };
  if (!adam7) return image(w, h);
  static constexpr std::uint64_t x0[7] = {0, 4, 0, 2, 0, 1, 0}, y0[7] = {0, 0, 4, 0, 2, 0, 1},
                                 dx[7] = {8, 8, 4, 4, 2, 2, 1}, dy[7] = {8, 8, 8, 4, 4, 2, 2};
  std::uint64_t n = 0;
  for (int p = 0; p < 7; ++p)
    n += image(w > x0[p] ? (w - x0[p] + dx[p] - 1) / dx[p] : 0,
               h > y0[p] ? (h - y0[p] + dy[p] - 1) / dy[p] : 0);
  return n;
}

}  // namespace

void write_depth_png(const std::filesystem::path& path, const DepthImage& image) {
  if (image.width <= 0 || image.height <= 0 ||
      image.data.size() != static_cast<std::size_t>(image.width) * image.height) {
    throw InputError(path.string() + ": depth image size does not match its data");
  }
  std::vector<unsigned char> raw;  // filter byte 0 + big-endian samples per row
  raw.reserve(static_cast<std::size_t>(image.height) * (1 + 2 * image.width));
  for (int r = 0; r < image.height; ++r) {
    raw.push_back(0);
    for (int c = 0; c < image.width; ++c) {
      const std::uint16_t d = image.data[static_cast<std::size_t>(r) * image.width + c];
      raw.push_back(static_cast<unsigned char>(d >> 8));
      raw.push_back(static_cast<unsigned char>(d & 0xFF));
    }
  }
  std::vector<unsigned char> z = {0x78, 0x01};  // zlib header, no compression
  for (std::size_t pos = 0; pos < raw.size() || pos == 0;) {
    const std::size_t len = std::min<std::size_t>(65535, raw.size() - pos);
    const bool last = pos + len == raw.size();
    z.push_back(last ? 1 : 0);
    z.push_back(static_cast<unsigned char>(len & 0xFF));
    z.push_back(static_cast<unsigned char>(len >> 8));
    z.push_back(static_cast<unsigned char>(~len & 0xFF));
    z.push_back(static_cast<unsigned char>((~len >> 8) & 0xFF));
    z.insert(z.end(), raw.begin() + static_cast<std::ptrdiff_t>(pos),
             raw.begin() + static_cast<std::ptrdiff_t>(pos + len));
    pos += len;
    if (last) break;
  }
  std::uint32_t a = 1, b = 0;  // Adler-32
  for (unsigned char ch : raw) {
    a = (a + ch) % 65521;
    b = (b + a) % 65521;
  }
  put32(z, (b << 16) | a);
  std::vector<unsigned char> ihdr;
  put32(ihdr, static_cast<std::uint32_t>(image.width));
  put32(ihdr, static_cast<std::uint32_t>(image.height));
  ihdr.insert(ihdr.end(), {16, 0, 0, 0, 0});  // 16-bit, grayscale, deflate, filter 0, no interlace
  write_file_atomic(
      path,
      [&](std::ostream& out) {
        const unsigned char sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
        out.write(reinterpret_cast<const char*>(sig), 8);
        chunk(out, "IHDR", ihdr);
        chunk(out, "IDAT", z);
        chunk(out, "IEND", {});
      },
      /*binary=*/true);
}

PngSize png_size(const std::filesystem::path& path) {
  const std::string file = path.string();
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(file + ": cannot open");
  // The signature, then the IHDR chunk: length, "IHDR", width and height big-endian.
  unsigned char head[25] = {};
  in.read(reinterpret_cast<char*>(head), sizeof head);
  static const unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  if (in.gcount() != sizeof head || std::memcmp(head, kSignature, 8) != 0 ||
      std::memcmp(head + 12, "IHDR", 4) != 0)
    throw InputError(file + ": not a readable PNG (no PNG header)");
  return {be32(head + 16), be32(head + 20), head[24]};
}

std::vector<char> read_png_checked(const std::filesystem::path& path) {
  const std::string file = path.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec) && std::filesystem::exists(path, ec))
    throw InputError(file + ": not a regular file");
  const PngSize size = png_size(path);
  // Each side first: two 32-bit sides multiplied would overflow (found by fuzz_depth_png).
  if (size.width > kMaxDepthPngSide || size.height > kMaxDepthPngSide ||
      size.width * size.height > kMaxDepthPngPixels)
    throw InputError(file + ": " + std::to_string(size.width) + "x" + std::to_string(size.height) +
                     " pixels is more than a camera image may have (" +
                     std::to_string(kMaxDepthPngPixels) + " pixels, " +
                     std::to_string(kMaxDepthPngSide) + " a side)");
  // A 16-bit PNG of the most pixels, stored uncompressed, is about 2 bytes a pixel: a
  // larger file is refused before it is read in.
  constexpr std::uintmax_t kMaxBytes =
      4 * static_cast<std::uintmax_t>(kMaxDepthPngPixels) + (1 << 20);
  const std::uintmax_t file_bytes = std::filesystem::file_size(path, ec);
  if (ec) throw InputError(file + ": cannot read (" + ec.message() + ")");
  if (file_bytes > kMaxBytes)
    throw InputError(file + ": " + std::to_string(file_bytes) +
                     " bytes is more than a camera PNG may have (" + std::to_string(kMaxBytes) +
                     ")");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(file + ": cannot open");
  std::vector<char> bytes(static_cast<std::size_t>(file_bytes));
  in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  bytes.resize(static_cast<std::size_t>(in.gcount()));
  // The signature and a whole IHDR chunk (13 bytes of data and a CRC), read below.
  if (bytes.size() < 33) throw InputError(file + ": not a readable PNG (its header is cut short)");
  // Every chunk must fit in the file: stb_image sizes its buffer by an IDAT chunk's declared
  // length before reading it, so a 117-byte file declaring 1.2 GB took 2 GiB (found by
  // fuzz_depth_png). And the first IDAT must hold data: stb_image copies a first empty one
  // into a buffer it has not allocated yet (memcpy to NULL, undefined behaviour).
  bool idat_seen = false;
  std::string idat;  // the image data, concatenated
  for (std::size_t at = 8; at + 8 <= bytes.size();) {
    const auto* c = reinterpret_cast<const unsigned char*>(bytes.data() + at);
    const auto length = static_cast<std::uint64_t>(be32(c));
    if (length + 12 > bytes.size() - at)
      throw InputError(file + ": not a readable PNG (the chunk at byte " + std::to_string(at) +
                       " declares " + std::to_string(length) + " bytes, the file has " +
                       std::to_string(bytes.size() - at - 8) + " after its header)");
    if (std::memcmp(c + 4, "IEND", 4) == 0) break;
    if (std::memcmp(c + 4, "IDAT", 4) == 0) {
      if (!idat_seen && length == 0)
        throw InputError(file + ": not a readable PNG (its first IDAT chunk, at byte " +
                         std::to_string(at) + ", is empty)");
      idat_seen = true;
      idat.append(bytes.data() + at + 8, static_cast<std::size_t>(length));
    }
    at += 12 + static_cast<std::size_t>(length);
  }
  // The image data must inflate to what the header's pixels hold, no more: stb_image
  // grows its buffer for as long as the stream goes on, so a 1x1 header over a few MB of
  // compressed zeros took gigabytes (deflate packs about 1000 bytes into one). Inflated
  // here into a buffer of exactly that size, which zlib may not overrun.
  const auto* h = reinterpret_cast<const unsigned char*>(bytes.data());
  const std::uint64_t raw =
      inflated_bytes(static_cast<std::uint64_t>(size.width),
                     static_cast<std::uint64_t>(size.height), h[24], h[25], h[28] == 1);
  if (idat_seen) {
    std::vector<char> out(static_cast<std::size_t>(raw) + 1);
    const int got = stbi_zlib_decode_buffer(out.data(), static_cast<int>(out.size()), idat.data(),
                                            static_cast<int>(idat.size()));
    if (got < 0 || static_cast<std::uint64_t>(got) > raw)
      throw InputError(file + ": not a readable PNG (its image data does not inflate to the " +
                       std::to_string(raw) + " bytes of its " + std::to_string(size.width) + "x" +
                       std::to_string(size.height) + " pixels: corrupt, or longer than they hold)");
  }
  return bytes;
}

DepthImage read_depth_png(const std::filesystem::path& path) {
  const std::string file = path.string();
  const std::vector<char> bytes = read_png_checked(path);
  const auto* data = reinterpret_cast<const stbi_uc*>(bytes.data());
  const int len = static_cast<int>(bytes.size());
  int w = 0, h = 0, comp = 0;
  if (!stbi_info_from_memory(data, len, &w, &h, &comp)) {
    throw InputError(file + ": not a readable PNG (" + stbi_failure_reason() + ")");
  }
  if (!stbi_is_16_bit_from_memory(data, len)) {
    throw InputError(file + ": depth PNG must be 16-bit, this one is 8-bit");
  }
  if (comp != 1) {
    throw InputError(file + ": depth PNG must have 1 channel, this one has " +
                     std::to_string(comp));
  }
  stbi_us* pixels = stbi_load_16_from_memory(data, len, &w, &h, &comp, 1);
  if (pixels == nullptr) throw InputError(file + ": corrupt PNG (" + stbi_failure_reason() + ")");
  DepthImage img;
  img.width = w;
  img.height = h;
  img.data.assign(pixels, pixels + static_cast<std::size_t>(w) * h);
  stbi_image_free(pixels);
  return img;
}

}  // namespace linksight::io
