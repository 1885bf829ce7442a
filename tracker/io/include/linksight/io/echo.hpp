#pragma once
/// @file The one rule for echoing input in a message (docs/reliability.md, "Echoing
/// input"): text from a file, a tracker or the command line is cut to a bounded length,
/// and control bytes, non-UTF-8 bytes and the characters that reorder or hide text are
/// escaped, so that every refusal prints as one line of what the input really holds.

#include <cstddef>
#include <string>
#include <string_view>

namespace linksight::io {

/// The most bytes of one echoed input text a message shows (before escaping).
inline constexpr std::size_t kMaxEcho = 80;
/// The longest message an error carries [bytes, after escaping]: a message names a file,
/// a line, a key and a value or two, each echoed within kMaxEcho.
inline constexpr std::size_t kMaxMessage = 2048;

/// `text` escaped: `\n`, `\r`, `\t`, `\xHH` for any other byte below 0x20, DEL and any
/// byte that is not part of well-formed UTF-8; `\u{XXXX}` for C1 controls and the
/// format characters that break, reorder or hide text (line and paragraph separators,
/// bidirectional controls, zero-width marks). Printable UTF-8 passes unchanged, and so
/// does a backslash: a literal "\x1B" in the input reads as an escaped ESC would (the
/// price of an idempotent escape).
[[nodiscard]] std::string escape_controls(std::string_view text);

/// An input text for a message: escape_controls of its first `max_bytes` bytes (cut at a
/// character boundary), then "... (N bytes)" when the text is longer.
[[nodiscard]] std::string echo(std::string_view text, std::size_t max_bytes = kMaxEcho);

/// A whole message as one printable line: escape_controls, then cut to kMaxMessage with
/// "... (N bytes)". Idempotent: a printable line is returned unchanged. Every InputError
/// passes its message through it, and the CLI every message it prints.
[[nodiscard]] std::string printable_line(std::string_view message);

/// True when `message` is what printable_line returns for it: no control byte, valid
/// UTF-8, within kMaxMessage bytes (the fuzz targets assert it of every refusal).
[[nodiscard]] bool is_printable_line(std::string_view message);

}  // namespace linksight::io
