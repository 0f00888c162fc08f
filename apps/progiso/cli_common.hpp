// apps/progiso/cli_common.hpp — JSON formatting and the refined field, shared by the command's
// subcommands.
#pragma once

#include <cmath>
#include <cstdio>
#include <memory>
#include <sstream>
#include <string>

#include <progiso/core/field/detail/subdivision.hpp>
#include <progiso/core/field/smoothing.hpp>
#include <progiso/core/field/volume.hpp>

namespace progiso::cli {

/// The field a subcommand refines: `data`, or its smoothed field when `s` is active (samples
/// computed on demand). A smoothing the data cannot take throws progiso::error naming `input`.
inline std::shared_ptr<const volume> smoothed_field(std::shared_ptr<const volume> data,
                                                    const smoothing& s, const std::string& input) {
  if (!s.active()) return data;
  try {
    check_smoothing(data->dims(), s);
  } catch (const error& e) {
    throw error(input + ": " + e.what());
  }
  return std::make_shared<const volume>(smooth(std::move(data), s));
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

/// The "smoothing" object of --stats-json: the parameters, the data's and the field's dims, the
/// subdivision levels applied (K + S, 0 without smoothing) and the fine samples the rule computed.
inline std::string smoothing_json(const smoothing& s, const volume& data, const volume& field) {
  std::ostringstream o;
  const auto dims = [&o](const volume& v) {
    o << "[" << v.dims()[0] << ", " << v.dims()[1] << ", " << v.dims()[2] << "]";
  };
  const detail::subdivision* sub = field.subdivided();
  o << "{\"enabled\": " << (sub != nullptr ? "true" : "false") << ", \"levels\": " << s.levels
    << ", \"from\": " << s.from << ", \"alpha\": " << json_number(s.alpha) << ", \"region\": ";
  if (s.region) {
    o << "[";
    for (std::size_t k = 0; k < 6; ++k) o << (k ? ", " : "") << (*s.region)[k];
    o << "]";
  } else {
    o << "null";
  }
  o << ", \"subdivision_levels\": " << (sub != nullptr ? s.levels + s.from : 0)
    << ", \"data_dims\": ";
  dims(data);
  o << ", \"field_dims\": ";
  dims(field);
  o << ", \"subdivided_samples\": " << (sub != nullptr ? sub->evaluations() : 0)
    << ", \"overshoot_bound\": " << json_number(sub != nullptr ? sub->overshoot() : 0.0) << "}";
  return o.str();
}

}  // namespace progiso::cli
