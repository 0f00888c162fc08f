#include <progiso/core/field/smoothing.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <utility>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/field/detail/subdivision.hpp>

namespace progiso {
namespace detail {
namespace {

// A linear combination of data samples (data index, weight), sorted by index, and whether a
// ghost sample entered it.
struct combination {
  std::vector<std::pair<std::int32_t, double>> terms;
  bool ghost = false;
};

combination unit(std::int32_t i) { return {{{i, 1.0}}, false}; }

// Σ c_k · x_k, dropping terms that cancel to zero.
combination mix(std::initializer_list<std::pair<double, const combination*>> parts) {
  combination r;
  for (const auto& [c, x] : parts) {
    if (c == 0.0) continue;
    r.ghost = r.ghost || x->ghost;
    for (const auto& [i, w] : x->terms) r.terms.emplace_back(i, c * w);
  }
  std::sort(r.terms.begin(), r.terms.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  std::size_t n = 0;
  for (std::size_t k = 0; k < r.terms.size(); ++k) {
    if (n > 0 && r.terms[n - 1].first == r.terms[k].first) {
      r.terms[n - 1].second += r.terms[k].second;
    } else {
      r.terms[n++] = r.terms[k];
    }
  }
  r.terms.resize(n);
  std::erase_if(r.terms, [](const auto& t) { return t.second == 0.0; });
  return r;
}

// The linear extrapolation 2 a − b, marked as a ghost.
combination ghost(const combination& a, const combination& b) {
  combination g = mix({{2.0, &a}, {-1.0, &b}});
  g.ghost = true;
  return g;
}

}  // namespace

// The per-level rule run on combinations instead of values: level 0 holds the control samples
// (data samples 0, 2^K, 2^{2K}…; a last one past the data is a ghost), each level inserts the
// midpoints by the mask with ghosts at the ends, and after K + S levels the first (n − 1)·2^S + 1
// entries are the rows.
subdivision_axis::subdivision_axis(std::int64_t n, int levels, int from, double alpha) {
  const std::int64_t fine = (n - 1) * (std::int64_t{1} << levels) + 1;
  std::vector<combination> cur;
  if (n == 1) {
    cur.push_back(unit(0));
  } else {
    const std::int64_t step = std::int64_t{1} << from;
    stride_ = static_cast<std::int32_t>(step);
    const std::int64_t controls = (n - 1 + step - 1) / step + 1;
    for (std::int64_t i = 0; i < controls; ++i) {
      if (i * step <= n - 1) {
        cur.push_back(unit(static_cast<std::int32_t>(i * step)));
      } else {
        PROGISO_ASSERT(i >= 2);
        cur.push_back(
            ghost(cur[static_cast<std::size_t>(i - 1)], cur[static_cast<std::size_t>(i - 2)]));
      }
    }
    const double a = -alpha / 16.0;
    const double b = (8.0 + alpha) / 16.0;
    for (int l = 0; l < levels + from; ++l) {
      const std::size_t m = cur.size();
      PROGISO_ASSERT(m >= 2);
      const combination left = ghost(cur[0], cur[1]);
      const combination right = ghost(cur[m - 1], cur[m - 2]);
      std::vector<combination> next;
      next.reserve(2 * m - 1);
      for (std::size_t i = 0; i < m; ++i) {
        next.push_back(cur[i]);
        if (i + 1 == m) break;
        const combination& p = i == 0 ? left : cur[i - 1];
        const combination& q = i + 2 == m ? right : cur[i + 2];
        next.push_back(mix({{a, &p}, {b, &cur[i]}, {b, &cur[i + 1]}, {a, &q}}));
      }
      cur = std::move(next);
    }
  }
  PROGISO_ASSERT(static_cast<std::int64_t>(cur.size()) >= fine);
  const auto count = static_cast<std::size_t>(fine);
  first_.assign(count, 0);
  weights_.assign(count * max_taps, 0.0);
  taps_.assign(count, 0);
  ghost_free_.assign(count, 1);
  reach_lo_.assign(count, 0);
  reach_hi_.assign(count, 0);
  for (std::size_t x = 0; x < count; ++x) {
    const combination& c = cur[x];
    PROGISO_ASSERT(!c.terms.empty());
    const std::int32_t lo = c.terms.front().first;
    const auto span = static_cast<std::size_t>((c.terms.back().first - lo) / stride_ + 1);
    if (span > max_taps) {
      throw error("smoothing: a row of the composed rule spans " + std::to_string(span) +
                  " control samples, more than the " + std::to_string(max_taps) + " supported");
    }
    double abs_sum = 0.0;
    for (const auto& [i, w] : c.terms) {
      PROGISO_ASSERT((i - lo) % stride_ == 0);
      weights_[x * max_taps + static_cast<std::size_t>((i - lo) / stride_)] = w;
      abs_sum += std::fabs(w);
    }
    max_abs_sum_ = std::max(max_abs_sum_, abs_sum);
    first_[x] = lo;
    taps_[x] = static_cast<std::uint8_t>(span);
    ghost_free_[x] = c.ghost ? 0 : 1;
    reach_lo_[x] = c.terms.front().first;
    reach_hi_[x] = c.terms.back().first;
  }
  // Suffix minimum of the first index, prefix maximum of the last: monotone, so the reach of an
  // interval [x0, x1] is [reach_lo(x0), reach_hi(x1)] and nested intervals reach nested boxes.
  for (std::size_t x = count - 1; x-- > 0;) reach_lo_[x] = std::min(reach_lo_[x], reach_lo_[x + 1]);
  for (std::size_t x = 1; x < count; ++x) reach_hi_[x] = std::max(reach_hi_[x], reach_hi_[x - 1]);
}

std::size_t subdivision_axis::byte_size() const noexcept {
  return first_.size() * sizeof(std::int32_t) + weights_.size() * sizeof(double) + taps_.size() +
         ghost_free_.size() + (reach_lo_.size() + reach_hi_.size()) * sizeof(std::int32_t);
}

namespace {

subdivision_axis make_axis(const index3& dims, std::size_t q, const smoothing& s, bool rule) {
  return rule ? subdivision_axis(dims[q], s.levels, s.from, s.alpha)
              : subdivision_axis(dims[q], s.levels, 0, 0.0);
}

}  // namespace

namespace {
std::uint64_t next_subdivision_id() noexcept {
  static std::atomic<std::uint64_t> next{1};
  // relaxed: only uniqueness matters, which fetch_add gives in any order.
  return next.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace

subdivision::subdivision(std::shared_ptr<const volume> data, const smoothing& s)
    : data_(std::move(data)),
      id_(next_subdivision_id()),
      spec_(s),
      smooth_{make_axis(data_->dims(), 0, s, true), make_axis(data_->dims(), 1, s, true),
              make_axis(data_->dims(), 2, s, true)},
      linear_{make_axis(data_->dims(), 0, s, false), make_axis(data_->dims(), 1, s, false),
              make_axis(data_->dims(), 2, s, false)} {
  PROGISO_ASSERT(data_->subdivided() == nullptr);
  double product = 1.0;
  for (std::size_t q = 0; q < 3; ++q) {
    dims_[q] = smooth_[q].size();
    product *= smooth_[q].max_abs_sum();
    const std::int64_t scale = std::int64_t{1} << s.levels;
    region_lo_[q] = s.region ? (*s.region)[q] * scale : 0;
    region_hi_[q] = s.region ? (*s.region)[q + 3] * scale : dims_[q] - 1;
  }
  lambda_ = (product - 1.0) / 2.0;
}

bool subdivision::smoothed_at(std::int64_t x, std::int64_t y, std::int64_t z) const noexcept {
  return x >= region_lo_[0] && x <= region_hi_[0] && y >= region_lo_[1] && y <= region_hi_[1] &&
         z >= region_lo_[2] && z <= region_hi_[2];
}

bool subdivision::ghost_free(std::int64_t x, std::int64_t y, std::int64_t z) const noexcept {
  const auto& a = smoothed_at(x, y, z) ? smooth_ : linear_;
  return a[0].ghost_free(x) && a[1].ghost_free(y) && a[2].ghost_free(z);
}

// Σ_z w_z Σ_y w_y Σ_x w_x f: the three rows applied one axis at a time, the x rows (TX taps)
// unrolled at compile time.
template <unsigned TX, class T>
double subdivision::evaluate(const T* f, const std::array<const subdivision_axis*, 3>& axes,
                             const index3& p) const noexcept {
  const index3& n = data_->dims();
  const std::int64_t sy = n[0];
  const std::int64_t sz = n[0] * n[1];
  const subdivision_axis& ax = *axes[0];
  const subdivision_axis& ay = *axes[1];
  const subdivision_axis& az = *axes[2];
  const unsigned ty = ay.taps(p[1]);
  const unsigned tz = az.taps(p[2]);
  const double* wx = ax.weights(p[0]);
  const double* wy = ay.weights(p[1]);
  const double* wz = az.weights(p[2]);
  const T* base = f + ax.first(p[0]) + ay.first(p[1]) * sy + az.first(p[2]) * sz;
  const std::int64_t dx = ax.stride();
  const std::int64_t dy = ay.stride() * sy;
  const std::int64_t dz = az.stride() * sz;
  double vz = 0.0;
  for (unsigned kz = 0; kz < tz; ++kz) {
    const T* fz = base + kz * dz;
    double vy = 0.0;
    for (unsigned ky = 0; ky < ty; ++ky) {
      const T* fx = fz + ky * dy;
      double vx = 0.0;
      for (unsigned kx = 0; kx < TX; ++kx) vx += wx[kx] * static_cast<double>(fx[kx * dx]);
      vy += wy[ky] * vx;
    }
    vz += wz[kz] * vy;
  }
  return vz;
}

template <class T>
double subdivision::evaluate(const T* f, const std::array<const subdivision_axis*, 3>& axes,
                             const index3& p) const noexcept {
  switch (axes[0]->taps(p[0])) {
    case 1:
      return evaluate<1>(f, axes, p);
    case 2:
      return evaluate<2>(f, axes, p);
    case 3:
      return evaluate<3>(f, axes, p);
    case 4:
      return evaluate<4>(f, axes, p);
    case 5:
      return evaluate<5>(f, axes, p);
    case 6:
      return evaluate<6>(f, axes, p);
    case 7:
      return evaluate<7>(f, axes, p);
    default:
      return evaluate<8>(f, axes, p);
  }
}

void subdivision::count() const noexcept {
  // The k-th thread that ever counts owns shard k (k < 63) and adds by a plain load and store,
  // with no read-modify-write; later threads share the last shard through fetch_add.
  static std::atomic<unsigned> next_slot{0};
  static constexpr auto shared_slot =
      static_cast<unsigned>(std::tuple_size_v<decltype(evaluations_)> - 1);
  // relaxed: the slot only needs to be unique per thread, which fetch_add gives in any order.
  thread_local const unsigned slot =
      std::min(next_slot.fetch_add(1, std::memory_order_relaxed), shared_slot);
  std::atomic<std::uint64_t>& n = evaluations_[slot].n;
  // relaxed (all three): a statistic; evaluations() sums the shards after the work it reports on
  // (the caller's join or snapshot orders them). An owned shard has this thread as its only writer.
  if (slot == shared_slot) {
    n.fetch_add(1, std::memory_order_relaxed);
  } else {
    n.store(n.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
  }
}

double subdivision::compute(std::int64_t x, std::int64_t y, std::int64_t z) const noexcept {
  count();
  const bool rule = smoothed_at(x, y, z);
  const auto& a = rule ? smooth_ : linear_;
  const std::array<const subdivision_axis*, 3> axes{&a[0], &a[1], &a[2]};
  const index3 p{x, y, z};
  return data_->visit_samples([&](const auto* f) { return evaluate(f, axes, p); });
}

subdivision::reach_box subdivision::reach(const ipoint& b0, const ipoint& b1) const noexcept {
  reach_box r;
  r.smoothed = true;
  for (std::size_t q = 0; q < 3; ++q) {
    r.smoothed = r.smoothed && b0[q] <= region_hi_[q] && b1[q] >= region_lo_[q];
  }
  for (std::size_t q = 0; q < 3; ++q) {
    r.lo[q] = linear_[q].reach_lo(b0[q]);
    r.hi[q] = linear_[q].reach_hi(b1[q]);
    if (r.smoothed) {
      r.lo[q] = std::min<std::int64_t>(r.lo[q], smooth_[q].reach_lo(b0[q]));
      r.hi[q] = std::max<std::int64_t>(r.hi[q], smooth_[q].reach_hi(b1[q]));
    }
  }
  return r;
}

namespace {

// The sample cache: refinement reads each fine sample many times (the vertices a split and its
// neighbours share, the stencils of the ranges, extraction), each read 5 to 30 multiply-adds from
// scattered data. Every thread keeps the last samples it read in a direct-mapped table of its own
// (no sharing, no locks), tagged with the subdivision's unique id so tables never mix fields:
// 4096 entries of 24 bytes, 96 KiB per thread that reads a smoothed field, allocated on its first
// read, whatever the field's size.
struct sample_cache {
  static constexpr std::size_t size = 4096;
  struct entry {
    std::uint64_t id = 0;  // 0: empty (ids start at 1)
    std::uint64_t linear = 0;
    double value = 0.0;
  };
  std::array<entry, size> entries{};
};

sample_cache& thread_sample_cache() {
  thread_local std::unique_ptr<sample_cache> cache;
  if (!cache) cache = std::make_unique<sample_cache>();
  return *cache;
}

sample_cache::entry& cache_entry(std::size_t linear) noexcept {
  // Fibonacci hashing: neighbouring samples of all three axes spread over the table.
  static_assert(sample_cache::size == std::size_t{1} << 12);
  const auto slot = static_cast<std::size_t>((linear * 0x9E3779B97F4A7C15ULL) >> 52);
  return thread_sample_cache().entries[slot];
}

}  // namespace

double subdivision::at(std::size_t linear) const noexcept {
  sample_cache::entry& e = cache_entry(linear);
  if (e.id == id_ && e.linear == linear) return e.value;
  const auto i = static_cast<std::int64_t>(linear);
  const std::int64_t xy = dims_[0] * dims_[1];
  const std::int64_t z = i / xy;
  const std::int64_t r = i - z * xy;
  const std::int64_t y = r / dims_[0];
  const double v = compute(r - y * dims_[0], y, z);
  e = {id_, linear, v};
  return v;
}

double subdivision::at(std::int64_t x, std::int64_t y, std::int64_t z) const noexcept {
  PROGISO_ASSERT(x >= 0 && y >= 0 && z >= 0 && x < dims_[0] && y < dims_[1] && z < dims_[2]);
  const auto linear = static_cast<std::size_t>(x + dims_[0] * (y + dims_[1] * z));
  sample_cache::entry& e = cache_entry(linear);
  if (e.id == id_ && e.linear == linear) return e.value;
  const double v = compute(x, y, z);
  e = {id_, linear, v};
  return v;
}

std::uint64_t subdivision::evaluations() const noexcept {
  std::uint64_t n = 0;
  // relaxed: see count().
  for (const shard& s : evaluations_) n += s.n.load(std::memory_order_relaxed);
  return n;
}

std::size_t subdivision::byte_size() const noexcept {
  std::size_t n = sizeof(*this);
  for (std::size_t q = 0; q < 3; ++q) n += smooth_[q].byte_size() + linear_[q].byte_size();
  return n;
}

double subdivided_at(const subdivision& s, std::size_t linear) noexcept { return s.at(linear); }

data_pyramid::data_pyramid(const volume& data, const parallel_loop& run) : data_pyramid(data) {
  build_slabs(0, slab_count(), run);
  finish();
}

data_pyramid::data_pyramid(const volume& data) : data_(&data) {
  const index3& dims = data.dims();
  level base;
  for (std::size_t q = 0; q < 3; ++q) base.n[q] = (dims[q] + 3) / 4;
  const auto count = static_cast<std::size_t>(base.n[0] * base.n[1] * base.n[2]);
  base.lo.assign(count, std::numeric_limits<double>::infinity());
  base.hi.assign(count, -std::numeric_limits<double>::infinity());
  levels_.push_back(std::move(base));
}

std::size_t data_pyramid::slab_count() const noexcept {
  return static_cast<std::size_t>(levels_.front().n[2]);
}

void data_pyramid::build_slabs(std::size_t first, std::size_t last, const parallel_loop& run) {
  const volume& data = *data_;
  const index3& dims = data.dims();
  level& base = levels_.front();
  // One slab of bricks (4 planes of data) per piece: the pieces write disjoint bricks.
  data.visit_samples([&](const auto* f) {
    run_loop(run, last - first, [&](std::size_t k) {
      const auto bz = static_cast<std::int64_t>(first + k);
      const std::int64_t z0 = bz * 4;
      const std::int64_t z1 = std::min(z0 + 4, dims[2]);
      for (std::int64_t z = z0; z < z1; ++z) {
        for (std::int64_t y = 0; y < dims[1]; ++y) {
          const auto* row = f + data.linear(0, y, z);
          for (std::int64_t x = 0; x < dims[0]; ++x) {
            const std::size_t b = base.at(x / 4, y / 4, bz);
            const auto value = static_cast<double>(row[x]);
            base.lo[b] = std::min(base.lo[b], value);
            base.hi[b] = std::max(base.hi[b], value);
          }
        }
      }
    });
  });
}

void data_pyramid::finish() {
  PROGISO_ASSERT(levels_.size() == 1);
  while (levels_.back().n[0] > 1 || levels_.back().n[1] > 1 || levels_.back().n[2] > 1) {
    const level& fine = levels_.back();
    level up;
    for (std::size_t q = 0; q < 3; ++q) up.n[q] = (fine.n[q] + 1) / 2;
    const auto n = static_cast<std::size_t>(up.n[0] * up.n[1] * up.n[2]);
    up.lo.assign(n, std::numeric_limits<double>::infinity());
    up.hi.assign(n, -std::numeric_limits<double>::infinity());
    for (std::int64_t z = 0; z < fine.n[2]; ++z) {
      for (std::int64_t y = 0; y < fine.n[1]; ++y) {
        for (std::int64_t x = 0; x < fine.n[0]; ++x) {
          const std::size_t from = fine.at(x, y, z);
          const std::size_t to = up.at(x / 2, y / 2, z / 2);
          up.lo[to] = std::min(up.lo[to], fine.lo[from]);
          up.hi[to] = std::max(up.hi[to], fine.hi[from]);
        }
      }
    }
    levels_.push_back(std::move(up));
  }
}

std::array<double, 2> data_pyramid::range(const index3& d0, const index3& d1) const noexcept {
  std::int64_t extent = 1;
  for (std::size_t q = 0; q < 3; ++q) extent = std::max(extent, d1[q] - d0[q] + 1);
  std::size_t k = 0;
  while (k + 1 < levels_.size() && extent > 2 * (std::int64_t{4} << k)) ++k;
  const level& lv = levels_[k];
  const int shift = 2 + static_cast<int>(k);
  double lo = std::numeric_limits<double>::infinity();
  double hi = -lo;
  for (std::int64_t z = d0[2] >> shift; z <= (d1[2] >> shift); ++z) {
    for (std::int64_t y = d0[1] >> shift; y <= (d1[1] >> shift); ++y) {
      for (std::int64_t x = d0[0] >> shift; x <= (d1[0] >> shift); ++x) {
        const std::size_t b = lv.at(x, y, z);
        lo = std::min(lo, lv.lo[b]);
        hi = std::max(hi, lv.hi[b]);
      }
    }
  }
  return {lo, hi};
}

std::size_t data_pyramid::byte_size() const noexcept {
  std::size_t b = 0;
  for (const level& lv : levels_) b += (lv.lo.size() + lv.hi.size()) * sizeof(double);
  return b;
}

diamond_range subdivided_range(const subdivision& sub, const data_pyramid& data, const ipoint& b0,
                               const ipoint& b1) noexcept {
  const subdivision::reach_box box = sub.reach(b0, b1);
  auto [lo, hi] = data.range(box.lo, box.hi);
  if (box.smoothed) {
    const double widen = sub.overshoot() * (hi - lo);
    lo -= widen;
    hi += widen;
  }
  diamond_range r;
  r.lo = lo;
  r.hi = hi;
  r.error = hi - lo;
  return r;
}

}  // namespace detail

void check_smoothing(const index3& dims, const smoothing& s) {
  if (s.levels < 0 || s.levels > 3) {
    throw error("smoothing: expected S (levels below the data) from 0 to 3, found " +
                std::to_string(s.levels));
  }
  if (s.from < 0 || s.from > 14) {
    throw error("smoothing: expected K (levels above the data) from 0 to 14, found " +
                std::to_string(s.from));
  }
  if (!(s.alpha > 0.0 && s.alpha < max_smoothing_alpha)) {
    throw error("smoothing: expected alpha in (0, 2(sqrt 5 - 1)) = (0, 2.4721), found " +
                std::to_string(s.alpha));
  }
  static constexpr std::array<char, 3> axis{'x', 'y', 'z'};
  for (std::size_t q = 0; q < 3; ++q) {
    if (dims[q] > 1 && (std::int64_t{1} << s.from) > dims[q] - 1) {
      throw error(std::string("smoothing: K = ") + std::to_string(s.from) +
                  " needs two samples 2^K = " + std::to_string(std::int64_t{1} << s.from) +
                  " apart on every axis, but " + axis[q] + " has " + std::to_string(dims[q]) +
                  " samples");
    }
    const std::int64_t fine = (dims[q] - 1) * (std::int64_t{1} << s.levels) + 1;
    if (fine > (std::int64_t{1} << 15) + 1) {
      throw error(std::string("smoothing: S = ") + std::to_string(s.levels) + " makes " +
                  std::to_string(fine) + " samples along " + axis[q] +
                  ", above the 32769 supported");
    }
    if (s.region) {
      const std::int64_t lo = (*s.region)[q];
      const std::int64_t hi = (*s.region)[q + 3];
      if (lo < 0 || hi > dims[q] - 1 || lo > hi) {
        throw error(std::string("smoothing: expected the region's ") + axis[q] +
                    " range within 0.." + std::to_string(dims[q] - 1) +
                    " with low <= high, found " + std::to_string(lo) + ".." + std::to_string(hi));
      }
    }
  }
}

volume::volume(std::shared_ptr<const detail::subdivision> sub, const volume& data, index3 dims,
               std::array<double, 2> range)
    : sub_(std::move(sub)),
      dims_(dims),
      type_(sample_type::f64),
      spacing_(data.spacing()),
      origin_(data.origin()),
      range_(range) {
  const double scale = static_cast<double>(std::int64_t{1} << sub_->spec().levels);
  for (double& s : spacing_) s /= scale;
}

volume smooth(std::shared_ptr<const volume> data, const smoothing& s) {
  if (!data) throw error("smoothing: expected a volume, found a null pointer");
  if (data->subdivided() != nullptr) {
    throw error("smoothing: expected a data volume, found one that is already smoothed");
  }
  check_smoothing(data->dims(), s);
  auto sub = std::make_shared<const detail::subdivision>(data, s);
  // value_range(): the data's range, widened by the overshoot bound (a bound, not a scan of
  // the fine samples).
  const auto [lo, hi] = data->value_range();
  const double widen = sub->overshoot() * (hi - lo);
  const index3 dims = sub->dims();
  const volume& d = *data;
  return volume(std::move(sub), d, dims, {lo - widen, hi + widen});
}

}  // namespace progiso
