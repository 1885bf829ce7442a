#pragma once
/// @file The error every reader throws: its message starts with the file it is about.

#include <stdexcept>
#include <string>

namespace linksight::io {

/// Bad input data. what() is one line: "<file>: <problem>".
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace linksight::io
