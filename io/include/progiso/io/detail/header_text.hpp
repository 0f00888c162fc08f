// progiso/io/detail/header_text.hpp — reading the text headers of volume files (NRRD,
// MetaImage): bounded lines, words, locale-independent numbers and file-name patterns, shared
// by the readers so that each parses the same way and within the same bounds.
//
// line_reader reads a header line by line through one 64 KiB buffer and keeps the offset of the
// next unread byte (where data attached to the header starts); a line is at most
// header_max_line_bytes and holds no NUL byte. Numbers are parsed with std::from_chars
// (independent of the locale), with a leading '+' accepted as C's scanf accepts it. A file name
// pattern holds one "%d" (optionally "%0Nd", N ≤ 9) between literal text and is expanded by
// format_number(), never by printf.
//
// Thread safety: no global state. Errors throw progiso::error naming the file.
#pragma once

#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <type_traits>
#include <vector>

#include <progiso/io/detail/file_input.hpp>

namespace progiso::detail {

inline constexpr std::size_t header_max_line_bytes = std::size_t{1} << 20;

// ---------------------------------------------------------------------------------------------
// Text.

[[nodiscard]] inline bool is_blank(char c) noexcept { return c == ' ' || c == '\t'; }

/// `s` without leading and trailing blanks (spaces and tabs).
[[nodiscard]] std::string_view trim(std::string_view s) noexcept;

/// `s` with ASCII letters in lower case.
[[nodiscard]] std::string lower(std::string_view s);

/// The blank-separated words of `s`.
[[nodiscard]] std::vector<std::string_view> words(std::string_view s);

// ---------------------------------------------------------------------------------------------
// Numbers. Locale-independent (std::from_chars); a leading '+' is accepted, as C's scanf does.

enum class parse_status : std::uint8_t { ok, syntax, range };

inline std::string_view without_plus(std::string_view t) noexcept {
  if (t.size() > 1 && t[0] == '+' && t[1] != '+' && t[1] != '-') t.remove_prefix(1);
  return t;
}

template <class Int>
parse_status to_integer(std::string_view t, Int& value) noexcept {
  t = without_plus(t);
  if (t.empty() || t[0] == '+') return parse_status::syntax;
  if constexpr (std::is_unsigned_v<Int>) {
    if (t[0] == '-') return parse_status::syntax;
  }
  const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), value);
  if (end != t.data() + t.size()) return parse_status::syntax;
  if (ec == std::errc::result_out_of_range) return parse_status::range;
  return ec == std::errc{} ? parse_status::ok : parse_status::syntax;
}

template <class Int>
std::optional<Int> to_integer(std::string_view t) noexcept {
  Int value{};
  if (to_integer(t, value) != parse_status::ok) return std::nullopt;
  return value;
}

/// A decimal floating-point number, "inf", "infinity" or "nan" (any case). A value beyond the
/// type's range gives what C's strtod gives: ±infinity, or a subnormal or signed zero.
template <class Real>
std::optional<Real> to_real(std::string_view t) noexcept {
  t = without_plus(t);
  if (t.empty() || t[0] == '+') return std::nullopt;
  const char* const last = t.data() + t.size();
  Real value{};
  const auto [end, ec] = std::from_chars(t.data(), last, value);
  if (end != last) return std::nullopt;
  if (ec == std::errc{}) return value;
  if (ec != std::errc::result_out_of_range) return std::nullopt;
  // from_chars stores nothing when the value leaves the type's range: take it in long double,
  // which holds every exponent a sane file writes, and round from there.
  const bool negative = t[0] == '-';
  long double wide = 0.0L;
  const std::from_chars_result r = std::from_chars(t.data(), last, wide);
  if (r.ec == std::errc{} && r.ptr == last) {
    if (std::fabs(wide) > static_cast<long double>(std::numeric_limits<Real>::max())) {
      return negative ? -std::numeric_limits<Real>::infinity()
                      : std::numeric_limits<Real>::infinity();
    }
    return static_cast<Real>(wide);
  }
  const std::size_t e = t.find_first_of("eE");
  const bool tiny = e != std::string_view::npos && e + 1 < t.size() && t[e + 1] == '-';
  if (tiny) return negative ? -Real{0} : Real{0};
  return negative ? -std::numeric_limits<Real>::infinity() : std::numeric_limits<Real>::infinity();
}

// ---------------------------------------------------------------------------------------------
// Header lines.

/// Reads the header of a file line by line through one buffer, keeping the offset of the next
/// unread byte (where attached data starts). Lines end in "\n" or "\r\n"; a last line may end
/// at the end of the file. Every byte is looked at a constant number of times.
class line_reader {
 public:
  /// `format` names the header in messages ("NRRD", "MetaImage").
  line_reader(input_file& in, std::string_view format);

  /// The first bytes of the file (at most n), valid before any line was read.
  [[nodiscard]] std::string_view head(std::size_t n) const noexcept {
    return {buf_.data(), std::min(n, end_)};
  }
  /// The offset of the first byte not yet read as part of a line.
  [[nodiscard]] std::uint64_t offset() const noexcept { return offset_; }
  /// The number of the last line read (1-based).
  [[nodiscard]] std::size_t number() const noexcept { return number_; }

  /// Reads the next line without its terminator; false at the end of the file. Throws when the
  /// line is longer than header_max_line_bytes or holds a NUL byte.
  bool next(std::string& line);

 private:
  bool fill();
  [[noreturn]] void too_long() const;

  input_file& in_;
  std::string_view format_;
  std::vector<char> buf_;
  std::size_t pos_ = 0;
  std::size_t end_ = 0;
  std::uint64_t offset_ = 0;
  std::size_t number_ = 0;
};

// ---------------------------------------------------------------------------------------------
// File name patterns.

/// "%d" with an optional 0 flag and a one-digit width, between literal text; expanded by
/// format_number(), never by printf.
struct name_pattern {
  std::string prefix;
  std::string suffix;
  bool zero_pad = false;
  unsigned width = 0;
};

/// `v` in decimal, padded to `width` with zeros (after the sign) or spaces (before it).
[[nodiscard]] std::string format_number(std::int64_t v, bool zero_pad, unsigned width);

/// Parses a file name pattern: nullopt with `problem` empty when `text` has no conversion (a
/// plain name; "%%" stands for "%"), nullopt with `problem` set (one line) when a conversion is
/// other than %d / %0Nd, its width above 9, or there is more than one.
[[nodiscard]] std::optional<name_pattern> parse_name_pattern(std::string_view text,
                                                             std::string& problem);

}  // namespace progiso::detail
