#include "linksight/io/ply.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "linksight/io/atomic_file.hpp"
#include "linksight/io/csv.hpp"
#include "linksight/io/error.hpp"
#include "linksight/tracker/limits.hpp"

namespace linksight::io {
namespace {

// A PLY line (header or ASCII vertex) is short; an unbounded getline would hold a line of
// any length (a 200 MB comment line cost 780 MB): kMaxPlyLine (limits.hpp) bounds it.

// The next line into `line` (without its '\n'); false at the end of the input. Throws
// fail(...) for a line of kMaxPlyLine bytes or more.
template <class Fail>
bool ply_line(std::istream& in, std::string& line, const Fail& fail) {
  bool too_long = false;
  if (!read_bounded_line(in, line, static_cast<std::size_t>(kMaxPlyLine), too_long)) return false;
  if (too_long)
    throw fail("a line of " + std::to_string(kMaxPlyLine) + " bytes or more (a PLY line is short)");
  return true;
}

enum class Type { i8, u8, i16, u16, i32, u32, f32, f64 };

bool parse_type(const std::string& s, Type& t) {
  static const std::pair<const char*, Type> names[] = {
      {"char", Type::i8},   {"int8", Type::i8},     {"uchar", Type::u8},   {"uint8", Type::u8},
      {"short", Type::i16}, {"int16", Type::i16},   {"ushort", Type::u16}, {"uint16", Type::u16},
      {"int", Type::i32},   {"int32", Type::i32},   {"uint", Type::u32},   {"uint32", Type::u32},
      {"float", Type::f32}, {"float32", Type::f32}, {"double", Type::f64}, {"float64", Type::f64}};
  for (const auto& [n, ty] : names) {
    if (s == n) {
      t = ty;
      return true;
    }
  }
  return false;
}

std::size_t type_size(Type t) {
  switch (t) {
    case Type::i8:
    case Type::u8:
      return 1;
    case Type::i16:
    case Type::u16:
      return 2;
    case Type::i32:
    case Type::u32:
    case Type::f32:
      return 4;
    case Type::f64:
      return 8;
  }
  return 0;
}

struct Property {
  std::string name;
  Type type = Type::f32;
  bool is_list = false;
};
struct Element {
  std::string name;
  std::size_t count = 0;
  std::vector<Property> props;
};

double read_binary(const char* p, Type t) {
  static_assert(std::endian::native == std::endian::little, "big-endian hosts not supported");
  switch (t) {
    case Type::i8: {
      std::int8_t v;
      std::memcpy(&v, p, 1);
      return v;
    }
    case Type::u8: {
      std::uint8_t v;
      std::memcpy(&v, p, 1);
      return v;
    }
    case Type::i16: {
      std::int16_t v;
      std::memcpy(&v, p, 2);
      return v;
    }
    case Type::u16: {
      std::uint16_t v;
      std::memcpy(&v, p, 2);
      return v;
    }
    case Type::i32: {
      std::int32_t v;
      std::memcpy(&v, p, 4);
      return v;
    }
    case Type::u32: {
      std::uint32_t v;
      std::memcpy(&v, p, 4);
      return v;
    }
    case Type::f32: {
      float v;
      std::memcpy(&v, p, 4);
      return v;
    }
    case Type::f64: {
      double v;
      std::memcpy(&v, p, 8);
      return v;
    }
  }
  return 0;
}

}  // namespace

Cloud read_ply(const std::filesystem::path& path) {
  const std::string file = path.string();
  auto fail = [&](const std::string& what) -> InputError { return InputError(file + ": " + what); };
  std::ifstream in(path, std::ios::binary);
  if (!in) throw fail("cannot open");
  std::string line;
  if (!ply_line(in, line, fail) || (line != "ply" && line != "ply\r")) throw fail("not a PLY file");

  enum class Format { ascii, binary_le } format = Format::ascii;
  bool have_format = false;
  std::vector<Element> elements;
  for (;;) {
    if (!ply_line(in, line, fail)) throw fail("truncated header (no end_header)");
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream ls(line);
    std::string word;
    ls >> word;
    if (word == "end_header") break;
    if (word == "comment" || word == "obj_info" || word.empty()) continue;
    if (word == "format") {
      std::string f, version;
      ls >> f >> version;
      if (f == "ascii") {
        format = Format::ascii;
      } else if (f == "binary_little_endian") {
        format = Format::binary_le;
      } else {
        throw fail("unsupported format '" + echo(f) + "' (ascii and binary_little_endian only)");
      }
      have_format = true;
    } else if (word == "element") {
      Element e;
      long long count = -1;
      ls >> e.name >> count;
      if (!ls || count < 0) throw fail("malformed element line '" + echo(line) + "'");
      e.count = static_cast<std::size_t>(count);
      elements.push_back(e);
    } else if (word == "property") {
      if (elements.empty()) throw fail("property before any element");
      Property p;
      std::string type;
      ls >> type;
      if (type == "list") {
        std::string count_type, item_type;
        ls >> count_type >> item_type >> p.name;
        p.is_list = true;
        if (!parse_type(count_type, p.type) || !parse_type(item_type, p.type)) {
          throw fail("unsupported property type in '" + echo(line) + "'");
        }
      } else {
        ls >> p.name;
        if (!parse_type(type, p.type)) {
          throw fail("unsupported property type '" + echo(type) + "' for '" + echo(p.name) + "'");
        }
      }
      elements.back().props.push_back(p);
    } else {
      throw fail("unknown header line '" + echo(line) + "'");
    }
  }
  if (!have_format) throw fail("missing format line");

  std::size_t vi = elements.size();
  for (std::size_t i = 0; i < elements.size(); ++i) {
    if (elements[i].name == "vertex") {
      vi = i;
      break;
    }
  }
  if (vi == elements.size()) throw fail("no vertex element");
  const Element& vertex = elements[vi];
  int ix = -1, iy = -1, iz = -1;
  for (std::size_t k = 0; k < vertex.props.size(); ++k) {
    const Property& p = vertex.props[k];
    int* slot = p.name == "x" ? &ix : p.name == "y" ? &iy : p.name == "z" ? &iz : nullptr;
    if (slot == nullptr) continue;
    if (p.is_list || (p.type != Type::f32 && p.type != Type::f64)) {
      throw fail("unsupported type for vertex property '" + echo(p.name) +
                 "' (float or double only)");
    }
    *slot = static_cast<int>(k);
  }
  if (ix < 0 || iy < 0 || iz < 0) {
    throw fail(std::string("vertex element lacks property ") + (ix < 0 ? "x" : iy < 0 ? "y" : "z"));
  }
  for (const Property& p : vertex.props) {
    if (p.is_list)
      throw fail("unsupported: list property '" + echo(p.name) + "' in the vertex element");
  }
  // Everything after the header, to check counts against before trusting them.
  const std::streamoff data_begin = in.tellg();
  in.seekg(0, std::ios::end);
  const auto remaining = static_cast<std::uint64_t>(in.tellg() - data_begin);
  in.seekg(data_begin);
  auto truncated = [&](std::uint64_t have) {
    return fail("truncated: header says " + std::to_string(vertex.count) + " vertices, file has " +
                std::to_string(have));
  };
  for (std::size_t i = 0; i < vi; ++i) {
    // Elements before the vertices must be skipped; lists have no fixed size in binary.
    for (const auto& p : elements[i].props) {
      if (p.is_list && format == Format::binary_le) {
        throw fail("unsupported: list property in element '" + elements[i].name +
                   "' before the vertices");
      }
    }
  }

  Cloud cloud;
  // An ASCII vertex takes at least 6 bytes ("0 0 0\n"): never reserve more than the file holds.
  cloud.reserve(static_cast<std::size_t>(std::min<std::uint64_t>(vertex.count, remaining / 6 + 1)));
  const bool vertex_is_last = vi + 1 == elements.size();
  if (format == Format::ascii) {
    std::size_t skip = 0;
    for (std::size_t i = 0; i < vi; ++i) skip += elements[i].count;
    for (std::size_t i = 0; i < skip; ++i) {
      if (!ply_line(in, line, fail)) throw fail("truncated before the vertex element");
    }
    std::vector<double> values(vertex.props.size());
    for (std::size_t i = 0; i < vertex.count; ++i) {
      if (!ply_line(in, line, fail)) {
        throw truncated(i);
      }
      std::istringstream ls(line);
      for (std::size_t k = 0; k < values.size(); ++k) {
        std::string tok;
        if (!(ls >> tok)) {
          throw fail("vertex " + std::to_string(i) + ": expected " + std::to_string(values.size()) +
                     " values");
        }
        if (k == static_cast<std::size_t>(ix) || k == static_cast<std::size_t>(iy) ||
            k == static_cast<std::size_t>(iz)) {
          // strtod, not stod: out-of-range values saturate (to +-inf or toward 0)
          // instead of throwing.
          char* end = nullptr;
          values[k] = std::strtod(tok.c_str(), &end);
          if (end != tok.c_str() + tok.size()) {
            throw fail("vertex " + std::to_string(i) + ": bad number '" + echo(tok) + "'");
          }
        }
      }
      cloud.push_back(static_cast<float>(values[ix]), static_cast<float>(values[iy]),
                      static_cast<float>(values[iz]));
    }
    if (vertex_is_last) {
      while (ply_line(in, line, fail)) {
        if (line.find_first_not_of(" \t\r") != std::string::npos) {
          throw fail("wrong vertex count: more data after " + std::to_string(vertex.count) +
                     " vertices");
        }
      }
    }
  } else {
    // Sizes in 64 bits with overflow checks: a hostile count must not wrap into a small
    // buffer. Anything larger than the file is simply truncated.
    auto mul = [&](std::uint64_t a, std::uint64_t b) {
      std::uint64_t r = 0;
      return __builtin_mul_overflow(a, b, &r) ? UINT64_MAX : r;
    };
    std::uint64_t skip = 0;
    for (std::size_t i = 0; i < vi; ++i) {
      std::uint64_t rec = 0;
      for (const auto& p : elements[i].props) rec += type_size(p.type);
      const std::uint64_t bytes = mul(rec, elements[i].count);
      skip = bytes > remaining - std::min(skip, remaining) ? UINT64_MAX : skip + bytes;
    }
    if (skip > remaining) throw fail("truncated before the vertex element");
    in.seekg(static_cast<std::streamoff>(skip), std::ios::cur);
    std::size_t rec = 0;
    std::vector<std::size_t> offset(vertex.props.size());
    for (std::size_t k = 0; k < vertex.props.size(); ++k) {
      offset[k] = rec;
      rec += type_size(vertex.props[k].type);
    }
    const std::uint64_t need = mul(rec, vertex.count);
    if (need > remaining - skip) throw truncated((remaining - skip) / rec);
    std::vector<char> buf(static_cast<std::size_t>(need));
    in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
    if (static_cast<std::uint64_t>(in.gcount()) != need)
      throw truncated(static_cast<std::uint64_t>(in.gcount()) / rec);
    for (std::size_t i = 0; i < vertex.count; ++i) {
      const char* r = buf.data() + i * rec;
      cloud.push_back(static_cast<float>(read_binary(r + offset[ix], vertex.props[ix].type)),
                      static_cast<float>(read_binary(r + offset[iy], vertex.props[iy].type)),
                      static_cast<float>(read_binary(r + offset[iz], vertex.props[iz].type)));
    }
    if (vertex_is_last && in.peek() != std::char_traits<char>::eof()) {
      throw fail("wrong vertex count: more data after " + std::to_string(vertex.count) +
                 " vertices");
    }
  }
  return cloud;
}

void write_ply(const std::filesystem::path& path, const Cloud& cloud) {
  write_file_atomic(
      path,
      [&](std::ostream& out) {
        out << "ply\nformat binary_little_endian 1.0\ncomment linksight cloud, metres, camera "
               "frame\nelement vertex "
            << cloud.size()
            << "\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
        out.write(reinterpret_cast<const char*>(cloud.xyz.data()),
                  static_cast<std::streamsize>(cloud.xyz.size() * sizeof(float)));
      },
      /*binary=*/true);
}

}  // namespace linksight::io
