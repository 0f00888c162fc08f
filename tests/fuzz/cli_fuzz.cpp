// Fuzz harness: the command's option parsing (apps/progiso/cli_options.hpp). The input is the
// argument list, NUL-separated; the parser must accept it or throw progiso::error with one
// line, and never touch a file.
#include <cstdint>
#include <string>
#include <vector>

#include <progiso/core/base/error.hpp>

#include "cli_options.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace progiso;
  std::vector<std::string> args;
  std::string current;
  for (const char c : fuzz::as_text(data, size)) {
    if (c == '\0') {
      args.push_back(std::move(current));
      current.clear();
      if (args.size() > 64) break;
    } else {
      current += c;
    }
  }
  if (!current.empty()) args.push_back(std::move(current));
  const auto check = [](const progiso::error& e) {
    const std::string what = e.what();
    if (what.empty()) __builtin_trap();
  };
  try {
    (void)cli::parse_extract(args);
  } catch (const progiso::error& e) {
    check(e);
  }
  if (!args.empty()) args[0] = "contour";
  try {
    (void)cli::parse_contour(args);
  } catch (const progiso::error& e) {
    check(e);
  }
  return 0;
}
