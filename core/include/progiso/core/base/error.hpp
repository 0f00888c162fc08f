// progiso/core/base/error.hpp — the one exception type thrown at progiso's API edge.
//
// Every recoverable failure that a caller can cause — a missing or malformed file, dims that
// do not match the file size, an unknown sample type, a NaN isovalue, an invalid option — is
// reported by throwing progiso::error with a message that names the file or parameter, what
// was expected and what was found. Nothing else is thrown on purpose (std::bad_alloc aside).
// Bugs are caught by PROGISO_ASSERT instead. The command-line tool maps progiso::error to one
// line on stderr and exit status 2.
#pragma once

#include <stdexcept>
#include <string>

#include <progiso/core/base/config.hpp>

namespace progiso {

/// A recoverable failure caused by input: its what() is a complete, single-line message.
class error : public std::runtime_error {
 public:
  explicit error(const std::string& message) : std::runtime_error(message) {}
};

}  // namespace progiso
