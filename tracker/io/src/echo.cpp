#include "linksight/io/echo.hpp"

#include <cstdint>
#include <cstdio>

namespace linksight::io {
namespace {

// Length of the well-formed UTF-8 sequence at s[i] and its code point, or 0 where the byte
// starts none (RFC 3629: no overlong forms, no surrogates, nothing above U+10FFFF).
std::size_t utf8_at(std::string_view s, std::size_t i, std::uint32_t& cp) {
  const auto b = [&](std::size_t k) { return static_cast<unsigned char>(s[i + k]); };
  const unsigned char c = b(0);
  if (c < 0x80) {
    cp = c;
    return 1;
  }
  std::size_t n = 0;
  std::uint32_t min = 0;
  if ((c & 0xE0) == 0xC0) {
    n = 2, cp = c & 0x1Fu, min = 0x80;
  } else if ((c & 0xF0) == 0xE0) {
    n = 3, cp = c & 0x0Fu, min = 0x800;
  } else if ((c & 0xF8) == 0xF0) {
    n = 4, cp = c & 0x07u, min = 0x10000;
  } else {
    return 0;
  }
  if (i + n > s.size()) return 0;
  for (std::size_t k = 1; k < n; ++k) {
    if ((b(k) & 0xC0) != 0x80) return 0;
    cp = (cp << 6) | (b(k) & 0x3Fu);
  }
  if (cp < min || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return 0;
  return n;
}

// C1 controls, and the characters that break, reorder or hide what a terminal shows: the
// soft hyphen, the Arabic letter mark, zero-width marks, the line and paragraph
// separators, bidi embeddings, overrides and isolates, word joiners, the BOM.
bool is_hidden(std::uint32_t cp) {
  return (cp >= 0x80 && cp <= 0x9F) || cp == 0xAD || cp == 0x61C ||
         (cp >= 0x200B && cp <= 0x200F) || (cp >= 0x2028 && cp <= 0x202E) ||
         (cp >= 0x2060 && cp <= 0x2069) || cp == 0xFEFF;
}

void append_hex(std::string& out, const char* format, unsigned value) {
  char buf[16];
  std::snprintf(buf, sizeof buf, format, value);
  out += buf;
}

// Escapes s[i, end) into out; returns where it stopped (end, or the character that would
// carry out past `limit` bytes).
std::size_t escape_into(std::string& out, std::string_view s, std::size_t end, std::size_t limit) {
  std::size_t i = 0;
  while (i < end) {
    std::uint32_t cp = 0;
    const std::size_t n = utf8_at(s, i, cp);
    std::string piece;
    if (n == 0) {
      append_hex(piece, "\\x%02X", static_cast<unsigned char>(s[i]));
    } else if (cp == '\n') {
      piece = "\\n";
    } else if (cp == '\r') {
      piece = "\\r";
    } else if (cp == '\t') {
      piece = "\\t";
    } else if (cp < 0x20 || cp == 0x7F) {
      append_hex(piece, "\\x%02X", cp);
    } else if (is_hidden(cp)) {
      append_hex(piece, "\\u{%04X}", cp);
    } else {
      piece.assign(s.substr(i, n));
    }
    const std::size_t step = n == 0 ? 1 : n;
    if (i + step > end || out.size() + piece.size() > limit) break;
    out += piece;
    i += step;
  }
  return i;
}

std::string cut_note(std::size_t bytes) { return "... (" + std::to_string(bytes) + " bytes)"; }

}  // namespace

std::string escape_controls(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  escape_into(out, text, text.size(), std::string::npos);
  return out;
}

std::string echo(std::string_view text, std::size_t max_bytes) {
  std::string out;
  const std::size_t end = text.size() < max_bytes ? text.size() : max_bytes;
  const std::size_t stop = escape_into(out, text, end, std::string::npos);
  if (stop < text.size()) out += cut_note(text.size());
  return out;
}

std::string printable_line(std::string_view message) {
  std::string out;
  const std::string note = cut_note(message.size());
  const std::size_t stop = escape_into(out, message, message.size(), kMaxMessage);
  if (stop < message.size()) {
    // Room for the note: the escaped text is cut again at a character boundary.
    out.clear();
    escape_into(out, message, message.size(), kMaxMessage - note.size());
    out += note;
  }
  return out;
}

bool is_printable_line(std::string_view message) {
  return message.size() <= kMaxMessage && escape_controls(message) == message;
}

}  // namespace linksight::io
