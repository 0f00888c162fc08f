#include <progiso/io/detail/header_text.hpp>

#include <cstring>

#include <progiso/core/base/error.hpp>

namespace progiso::detail {

namespace {
constexpr std::size_t chunk_bytes = 64 * 1024;
}  // namespace

std::string_view trim(std::string_view s) noexcept {
  while (!s.empty() && is_blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_blank(s.back())) s.remove_suffix(1);
  return s;
}

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) {
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
  }
  return out;
}

std::vector<std::string_view> words(std::string_view s) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && is_blank(s[i])) ++i;
    const std::size_t start = i;
    while (i < s.size() && !is_blank(s[i])) ++i;
    if (i > start) out.push_back(s.substr(start, i - start));
  }
  return out;
}

line_reader::line_reader(input_file& in, std::string_view format)
    : in_(in), format_(format), buf_(chunk_bytes) {
  fill();
}

bool line_reader::next(std::string& line) {
  line.clear();
  bool any = false;
  for (;;) {
    if (pos_ == end_ && !fill()) break;
    any = true;
    const char* begin = buf_.data() + pos_;
    const std::size_t avail = end_ - pos_;
    const auto* nl = static_cast<const char*>(std::memchr(begin, '\n', avail));
    const std::size_t n = nl != nullptr ? static_cast<std::size_t>(nl - begin) : avail;
    if (std::memchr(begin, '\0', n) != nullptr) {
      throw error(in_.path().string() + ": " + std::string(format_) + " header line " +
                  std::to_string(number_ + 1) + " holds a NUL byte (expected text)");
    }
    // One byte more than the bound for a "\r" before the "\n".
    if (line.size() + n > header_max_line_bytes + 1) too_long();
    line.append(begin, n);
    pos_ += n;
    offset_ += n;
    if (nl != nullptr) {
      ++pos_;
      ++offset_;
      break;
    }
  }
  if (!any) return false;
  ++number_;
  if (!line.empty() && line.back() == '\r') line.pop_back();
  if (line.size() > header_max_line_bytes) too_long();
  return true;
}

bool line_reader::fill() {
  pos_ = 0;
  end_ = in_.read(buf_.data(), buf_.size());
  return end_ > 0;
}

void line_reader::too_long() const {
  throw error(in_.path().string() + ": " + std::string(format_) + " header line " +
              std::to_string(number_ + 1) + " is longer than " +
              std::to_string(header_max_line_bytes) + " bytes");
}

std::string format_number(std::int64_t v, bool zero_pad, unsigned width) {
  const std::string digits = std::to_string(v < 0 ? -v : v);
  const std::string sign = v < 0 ? "-" : "";
  const std::size_t len = sign.size() + digits.size();
  if (len >= width) return sign + digits;
  const std::string pad(width - len, zero_pad ? '0' : ' ');
  return zero_pad ? sign + pad + digits : pad + sign + digits;
}

std::optional<name_pattern> parse_name_pattern(std::string_view text, std::string& problem) {
  problem.clear();
  name_pattern p;
  bool have = false;
  std::string* part = &p.prefix;
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text[i] != '%') {
      *part += text[i];
      continue;
    }
    if (i + 1 < text.size() && text[i + 1] == '%') {
      *part += '%';
      ++i;
      continue;
    }
    std::size_t j = i + 1;
    const bool zero_pad = j < text.size() && text[j] == '0';
    if (zero_pad) ++j;
    const std::size_t width_begin = j;
    while (j < text.size() && text[j] >= '0' && text[j] <= '9') ++j;
    const std::string_view width = text.substr(width_begin, j - width_begin);
    if (j == text.size() || text[j] != 'd') {
      problem = "unsupported conversion " +
                detail::quoted(text.substr(i, std::min(j + 1, text.size()) - i)) +
                " in the file name pattern (expected one %d, optionally %0Nd with N ≤ 9)";
      return std::nullopt;
    }
    if (width.size() > 1) {
      problem = "field width " + detail::quoted(width) +
                " in the file name pattern is above the limit of 9";
      return std::nullopt;
    }
    if (have) {
      problem = "the file name pattern " + detail::quoted(text) +
                " has more than one conversion (expected one %d)";
      return std::nullopt;
    }
    have = true;
    p.zero_pad = zero_pad;
    p.width = width.empty() ? 0u : static_cast<unsigned>(width[0] - '0');
    part = &p.suffix;
    i = j;
  }
  if (!have) return std::nullopt;
  return p;
}

}  // namespace progiso::detail
