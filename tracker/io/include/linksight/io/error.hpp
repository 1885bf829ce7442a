#pragma once
/// @file The error every reader throws: its message starts with the file it is about.

#include <stdexcept>
#include <string>

#include "linksight/io/echo.hpp"

namespace linksight::io {

/// Bad input data. what() is one printable line, "<file>: <problem>": the message passes
/// through printable_line (echo.hpp), so input echoed into it can neither break the line
/// nor reach the terminal as control bytes, however the message was put together.
class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& what) : std::runtime_error(printable_line(what)) {}
  explicit InputError(const char* what) : InputError(std::string(what)) {}
};

}  // namespace linksight::io
