// apps/progiso/cli_options.hpp — the command line of `progiso extract` and `progiso contour`,
// parsed into plain structs. Pure: no file is touched, nothing is printed, nothing exits, so
// the parser can be fuzzed (fuzz/cli_options_fuzz.cpp) and tested on its own. Every bad
// argument throws progiso::error with one line that names the option and what was found.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <progiso/core/contour/contour_refiner.hpp>
#include <progiso/core/field/smoothing.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/core/refine/goal.hpp>
#include <progiso/core/refine/refiner.hpp>

namespace progiso::cli {

extern const char* const usage_text;

/// A finite double, written as C's strtod would accept it without leading spaces (an
/// optional sign, decimal or hexadecimal digits, an exponent); subnormal values such as
/// 1e-320 are numbers too. Throws "FLAG: expected a number, found 'TEXT'" or "FLAG: expected a
/// finite number …" for overflow, inf and nan.
[[nodiscard]] double parse_number(const std::string& flag, const std::string& text);

/// A non-negative integer up to 2^64 − 1, written in decimal or as an integral number such as
/// 1e6. Throws "FLAG: expected a non-negative integer …" otherwise (also beyond 2^64 − 1).
[[nodiscard]] std::uint64_t parse_count(const std::string& flag, const std::string& text);

struct extract_arguments {
  bool help = false;
  std::optional<std::string> input;
  bool demo = false;
  std::optional<std::string> output;
  std::optional<double> iso;
  std::optional<index3> dims;
  std::optional<sample_type> type;
  bool big_endian = false;
  std::optional<std::array<double, 3>> spacing;
  bool world = false;                  // --world: vertices in the file's scanner coordinates
  std::optional<std::string> series;   // --series: which series of a DICOM directory
  std::optional<std::int64_t> volume;  // --volume: which volume of a NIfTI time series
  std::optional<std::int64_t> level;   // --level: which level of an OME-Zarr pyramid
  extract_options options;
  std::chrono::duration<double> time_budget{0.0};  // --time-ms, until the volume is in memory
  std::optional<std::string> stats_json;
  std::optional<std::string> hierarchy;  // --hierarchy: the engine's records as a stream (.pgh)
  unsigned threads = 0;                  // 0: all cores
  smoothing smooth;
};

/// `progiso cut`: a cut of a hierarchy stream, without the volume.
struct cut_arguments {
  enum class mode { all, error, triangles, region };
  bool help = false;
  std::optional<std::string> input;
  std::optional<std::string> output;
  mode how = mode::all;
  double max_error = 0.0;
  std::uint64_t max_triangles = 0;
  std::array<double, 6> region{};  // X0, Y0, Z0, X1, Y1, Z1 (grid coordinates, inclusive)
  std::uint64_t records = ~std::uint64_t{0};  // --records N: the stream's first N records
  std::optional<std::string> stats_json;
};

struct contour_arguments {
  bool help = false;
  std::optional<std::string> input;
  std::optional<std::string> output;
  std::vector<double> isovalues;
  contour_options options;
  std::chrono::duration<double> time_budget{0.0};  // --time-ms, until the image is in memory
  std::optional<std::string> frames;
  std::optional<std::string> stats_json;
  smoothing smooth;  // region: X0, Y0, 0, X1, Y1, 0
};

/// A --time-ms goal's deadline, counted from now (the input is in memory); other goals as they
/// are.
template <class Arguments>
void start_deadline(Arguments& a) {
  if (a.options.goal.what == refine_goal::kind::deadline) {
    a.options.goal = refine_goal::within(a.time_budget);
  }
}

/// The goal's name in --stats-json: "full", "error", `budget_name`, "time".
[[nodiscard]] const char* goal_name(const refine_goal& goal, const char* budget_name) noexcept;

/// `args` is argv without the program name, starting with "extract". Throws progiso::error.
/// `under_mpi`: one rank of an MPI job, which may also write a .pvtp (one piece per rank).
[[nodiscard]] extract_arguments parse_extract(const std::vector<std::string>& args,
                                              bool under_mpi = false);
/// `args` is argv without the program name, starting with "cut". Throws progiso::error.
[[nodiscard]] cut_arguments parse_cut(const std::vector<std::string>& args);
/// `args` is argv without the program name, starting with "contour". Throws progiso::error.
[[nodiscard]] contour_arguments parse_contour(const std::vector<std::string>& args);

}  // namespace progiso::cli
