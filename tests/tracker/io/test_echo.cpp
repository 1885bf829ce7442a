// echo.hpp and json_input.hpp: input echoed into a message is one printable line of
// bounded length; untrusted JSON is bounded in depth and size before it is parsed.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <fstream>
#include <string>

#include "linksight/io/echo.hpp"
#include "linksight/io/error.hpp"
#include "linksight/io/json_input.hpp"
#include "test_support.hpp"

namespace linksight::io {
namespace {
namespace fs = std::filesystem;

TEST(Echo, ControlAndNonUtf8BytesAreEscaped) {
  EXPECT_EQ(escape_controls("a\nb\rc\td"), "a\\nb\\rc\\td");
  // A screen-clearing escape sequence, a bell, DEL and a NUL.
  EXPECT_EQ(escape_controls(std::string("\x1b[2J\x07\x7f", 6) + std::string(1, '\0')),
            "\\x1B[2J\\x07\\x7F\\x00");
  // Invalid UTF-8: a lone continuation byte, an overlong '/', a surrogate, a cut sequence.
  EXPECT_EQ(escape_controls("\x80"), "\\x80");
  EXPECT_EQ(escape_controls("\xC0\xAF"), "\\xC0\\xAF");
  EXPECT_EQ(escape_controls("\xED\xA0\x80"), "\\xED\\xA0\\x80");
  EXPECT_EQ(escape_controls("x\xE2\x82"), "x\\xE2\\x82");
  // Printable UTF-8 passes; a C1 control, a right-to-left override and a zero-width space
  // do not.
  EXPECT_EQ(escape_controls("Größe 5 µm"), "Größe 5 µm");
  // ("\x32" is '2' and "\x62" 'b': a hex escape would take a following digit or letter.)
  EXPECT_EQ(escape_controls("\xC2\x9B\x32J"), "\\u{009B}2J");
  EXPECT_EQ(escape_controls("a\xE2\x80\xAE\x62"), "a\\u{202E}b");
  EXPECT_EQ(escape_controls("a\xE2\x80\x8B\x62"), "a\\u{200B}b");
  EXPECT_EQ(escape_controls("a\xE2\x80\xA8\x62"), "a\\u{2028}b");  // a line separator
}

TEST(Echo, LongTextIsCutAtACharacterWithItsSize) {
  EXPECT_EQ(echo("short"), "short");
  const std::string long_text(1000, 'k');
  EXPECT_EQ(echo(long_text), std::string(kMaxEcho, 'k') + "... (1000 bytes)");
  // A two-byte character across the cut is left out whole, not halved.
  EXPECT_EQ(echo("ab\xC3\xA9", 3), "ab... (4 bytes)");
  EXPECT_EQ(echo("ab\xC3\xA9", 4), "ab\xC3\xA9");
}

TEST(Echo, APrintableLineIsBoundedAndIdempotent) {
  const std::string attack = "key\r\x1b[2Jlinksight: all good\n" + std::string(10000, 'x');
  const std::string line = printable_line(attack);
  EXPECT_TRUE(is_printable_line(line)) << line;
  EXPECT_LE(line.size(), kMaxMessage);
  EXPECT_EQ(line.find('\r'), std::string::npos);
  EXPECT_NE(line.find("key\\r\\x1B[2Jlinksight: all good\\n"), std::string::npos) << line;
  EXPECT_NE(line.find("... (10028 bytes)"), std::string::npos) << line;
  EXPECT_EQ(printable_line(line), line);
  EXPECT_FALSE(is_printable_line(attack));
  EXPECT_FALSE(is_printable_line(std::string(kMaxMessage + 1, 'x')));
}

TEST(Echo, EveryInputErrorIsOnePrintableLine) {
  const InputError e("scene.yaml:3: unknown key 'a\nlinksight: all good\r'");
  EXPECT_STREQ(e.what(), "scene.yaml:3: unknown key 'a\\nlinksight: all good\\r'");
  EXPECT_TRUE(is_printable_line(InputError(std::string(100000, '\x1b')).what()));
}

TEST(JsonInput, DepthIsBoundedOutsideStrings) {
  const auto nested = [](std::size_t depth) {
    return std::string(depth, '[') + std::string(depth, ']');
  };
  EXPECT_EQ(json_too_deep_at(nested(kMaxJsonDepth)), std::string_view::npos);
  EXPECT_EQ(json_too_deep_at(nested(kMaxJsonDepth + 1)), kMaxJsonDepth);
  // Brackets inside strings, escaped quotes included, do not nest.
  EXPECT_EQ(json_too_deep_at("{\"k\": \"" + std::string(1000, '[') + "\\\"[[\"}"),
            std::string_view::npos);
  EXPECT_EQ(json_too_deep_at("{\"a\":" + std::string(100000, '{')), 68u);  // 65th level
  try {
    check_json_depth(nested(100000), "answer.json");
    ADD_FAILURE() << "100,000 levels passed";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "answer.json: JSON nested deeper than 64 levels (byte 64)");
  }
}

TEST(JsonInput, AFileIsCheckedBeforeParsing) {
  const fs::path dir = test::scratch_dir("JsonInput.AFileIsChecked");
  const auto error_of = [](const fs::path& p) -> std::string {
    try {
      (void)read_json_file(p, "no such file (a recording?)");
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  };
  std::ofstream(dir / "ok.json") << "{\"a\": [1, 2]}";
  EXPECT_EQ(read_json_file(dir / "ok.json", ""), "{\"a\": [1, 2]}");
  EXPECT_EQ(error_of(dir / "none.json"),
            (dir / "none.json").string() + ": no such file (a recording?)");
  std::ofstream(dir / "deep.json") << std::string(70, '[');
  EXPECT_EQ(error_of(dir / "deep.json"),
            (dir / "deep.json").string() + ": JSON nested deeper than 64 levels (byte 64)");
  // A device and a FIFO are refused before a byte is read: neither ends nor waits.
  EXPECT_EQ(error_of("/dev/zero"), "/dev/zero: not a regular file");
  ASSERT_EQ(::mkfifo((dir / "fifo.json").c_str(), 0600), 0);
  EXPECT_EQ(error_of(dir / "fifo.json"), (dir / "fifo.json").string() + ": not a regular file");
  EXPECT_EQ(error_of(dir), dir.string() + ": not a regular file");
  {
    std::ofstream big(dir / "big.json");
    big << '"' << std::string(kMaxJsonFileBytes, 'x') << '"';
  }
  EXPECT_NE(
      error_of(dir / "big.json").find("big.json: 16777218 bytes, more than a JSON input may have"),
      std::string::npos);
}

}  // namespace
}  // namespace linksight::io
