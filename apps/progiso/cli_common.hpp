// apps/progiso/cli_common.hpp — small helpers shared by the command's subcommands: number and
// list parsing with one-line errors, atomic text output, JSON formatting.
#pragma once

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <system_error>
#include <vector>

#include <progiso/core/detail/file_output.hpp>
#include <progiso/core/error.hpp>

namespace progiso::cli {

using progiso::error;

inline double parse_number(const std::string& flag, const std::string& text) {
  std::size_t used = 0;
  double v = 0.0;
  try {
    v = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != text.size() || text.empty()) {
    throw error(flag + ": expected a number, found '" + text + "'");
  }
  if (!std::isfinite(v)) throw error(flag + ": expected a finite number, found '" + text + "'");
  return v;
}

inline std::vector<std::string> split_commas(const std::string& flag, const std::string& text) {
  std::vector<std::string> parts;
  std::stringstream ss(text);
  std::string p;
  while (std::getline(ss, p, ',')) parts.push_back(p);
  if (parts.size() != 3 || text.back() == ',') {
    throw error(flag + ": expected three comma-separated values, found '" + text + "'");
  }
  return parts;
}

/// Writes `text` to `file` all or nothing (see detail::atomic_output).
inline void write_text_atomically(const std::filesystem::path& file, const std::string& text) {
  progiso::detail::atomic_output out(file);
  out.write(text);
  out.commit();
}

inline std::string json_number(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

inline std::string json_escape(const std::string& s) {
  std::string o;
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      o += '\\';
      o += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", c);
      o += buf;
    } else {
      o += c;
    }
  }
  return o;
}

/// The value after option argv[i] (advancing i), or a one-line error naming the option.
inline std::string next_value(int argc, char** argv, int& i, const std::string& flag) {
  if (i + 1 >= argc) throw error(flag + ": missing value");
  return argv[++i];
}

/// Splits "a,b,c" into any number (≥ 1) of non-empty parts.
inline std::vector<std::string> split_list(const std::string& flag, const std::string& text) {
  std::vector<std::string> parts;
  std::stringstream ss(text);
  std::string p;
  while (std::getline(ss, p, ',')) parts.push_back(p);
  if (parts.empty() || text.back() == ',') {
    throw error(flag + ": expected comma-separated values, found '" + text + "'");
  }
  return parts;
}

}  // namespace progiso::cli
