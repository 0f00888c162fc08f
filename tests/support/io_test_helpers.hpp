// tests/support/io_test_helpers.hpp — small helpers shared by the reader and writer tests.
#pragma once

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include <progiso/core/base/error.hpp>

namespace progiso::test {

/// Writes `bytes` to `file` (binary, truncating); fails the test when that does not work.
inline void write_file(const std::filesystem::path& file, const std::string& bytes) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out << bytes;
  ASSERT_TRUE(out.good()) << file;
}

/// The message of the progiso::error that `f` throws; checks that it is one line starting with
/// the file name followed by `after` (": ", or ":" where a line number follows).
template <class F>
std::string error_message_naming(const std::filesystem::path& file, F&& f,
                                 const std::string& after = ": ") {
  try {
    f();
  } catch (const progiso::error& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind(file.string() + after, 0), 0u) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    return message;
  }
  ADD_FAILURE() << "expected progiso::error for " << file;
  return {};
}

/// The whole file as bytes ("" when it cannot be read).
inline std::string read_whole_file(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

inline bool contains(const std::string& haystack, const std::string& needle) {
  return haystack.find(needle) != std::string::npos;
}

}  // namespace progiso::test
