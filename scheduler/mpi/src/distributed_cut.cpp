#include <progiso/mpi/detail/distributed_cut.hpp>

#include <algorithm>
#include <cstring>
#include <limits>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/mpi/detail/messages.hpp>
#include <progiso/scheduler/tbb_environment.hpp>

namespace progiso::detail {

namespace {

constexpr int tag_bundle = 31;

int comm_rank(MPI_Comm comm) {
  int r = 0;
  MPI_Comm_rank(comm, &r);
  return r;
}
int comm_size(MPI_Comm comm) {
  int n = 1;
  MPI_Comm_size(comm, &n);
  return n;
}

// A bundle: the new splits of the ranks of a subtree of the gather, each rank's as a head and
// then its split and group records.
struct bundle_head {
  std::int64_t rank;
  std::uint64_t splits;
  std::uint64_t groups;
};

void append_to_bundle(std::vector<char>& b, int rank, std::span<const share_split> splits,
                      std::span<const packed_group> groups) {
  const bundle_head h{rank, splits.size(), groups.size()};
  const auto add = [&b](const void* p, std::size_t n) {
    const auto* c = static_cast<const char*>(p);
    b.insert(b.end(), c, c + n);
  };
  add(&h, sizeof h);
  add(splits.data(), splits.size_bytes());
  add(groups.data(), groups.size_bytes());
}

// The ranks' pieces of a bundle the root received; throws progiso::error for a bundle whose heads
// do not add up to its bytes or name a rank twice, the root, or one outside the communicator.
std::vector<std::pair<int, share_splits>> read_bundle(const std::vector<char>& b, int size,
                                                      int root) {
  std::vector<std::pair<int, share_splits>> out;
  std::vector<bool> seen(static_cast<std::size_t>(size), false);
  seen[static_cast<std::size_t>(root)] = true;
  std::size_t at = 0;
  const auto take = [&](void* p, std::uint64_t n) {
    if (n > b.size() - at) throw error("a rank sent a bundle of splits shorter than its heads say");
    if (n > 0) std::memcpy(p, b.data() + at, static_cast<std::size_t>(n));
    at += static_cast<std::size_t>(n);
  };
  while (at < b.size()) {
    bundle_head h{};
    take(&h, sizeof h);
    if (h.rank < 0 || h.rank >= size || seen[static_cast<std::size_t>(h.rank)] ||
        h.splits > (b.size() - at) / sizeof(share_split) ||
        h.groups > (b.size() - at) / sizeof(packed_group)) {
      throw error("a rank sent a bundle of splits with a bad head (rank " + std::to_string(h.rank) +
                  ")");
    }
    seen[static_cast<std::size_t>(h.rank)] = true;
    share_splits piece;
    piece.splits.resize(static_cast<std::size_t>(h.splits));
    piece.groups.resize(static_cast<std::size_t>(h.groups));
    take(piece.splits.data(), h.splits * sizeof(share_split));
    take(piece.groups.data(), h.groups * sizeof(packed_group));
    out.emplace_back(static_cast<int>(h.rank), std::move(piece));
  }
  return out;
}

/// A small all-reduce that waits politely (the slowest rank may be a round behind).
template <class T>
void allreduce_politely(T* values, int count, MPI_Datatype type, MPI_Op op, MPI_Comm comm) {
  MPI_Request request = MPI_REQUEST_NULL;
  MPI_Iallreduce(MPI_IN_PLACE, values, count, type, op, comm, &request);
  wait_politely(request);
}

}  // namespace

distributed_cut::distributed_cut(MPI_Comm comm, int root, const volume& vol, double isovalue)
    : comm_(comm),
      rank_(comm_rank(comm)),
      size_(comm_size(comm)),
      root_(root),
      vol_(vol),
      hier_(vol.dims()),
      ranges_(vol, hier_, range_data::staged),
      share_(error_cut_share(hier_, ranges_.piece_count(), static_cast<std::size_t>(rank_),
                             static_cast<std::size_t>(size_))),
      isovalue_(isovalue),
      threshold_(std::numeric_limits<double>::infinity()) {
  if (root < 0 || root >= size_) {
    throw error("the root rank " + std::to_string(root) + " is not a rank of the communicator (" +
                std::to_string(size_) + " ranks)");
  }
  if (rank_ == root_) groups_seen_.resize(static_cast<std::size_t>(size_));
}

distributed_cut::~distributed_cut() = default;

bool distributed_cut::build_ranges(unsigned threads, const std::function<bool()>& stop) {
  int built = 1;
  scheduler::run_on_threads(threads, [&](const parallel_loop& loop, std::size_t parts) {
    const std::size_t step = stop ? std::max<std::size_t>(parts, 1) : share_.piece_end;
    for (std::size_t p = share_.piece_begin; p < share_.piece_end; p += step) {
      if (stop && stop()) {
        built = 0;
        break;
      }
      ranges_.build_pieces_with_errors(p, std::min(share_.piece_end, p + step), loop);
    }
  });
  MPI_Allreduce(MPI_IN_PLACE, &built, 1, MPI_INT, MPI_MIN, comm_);
  if (built == 0) return false;
  // Every rank's pieces to every rank, in place: counts and offsets in pieces (one plane of
  // bricks each), so that no count passes an int however large the grid.
  const std::size_t piece = ranges_.piece_bytes(0, 1).size();
  if (piece == 0 || piece > 2147483647u) {
    throw error("the range data's pieces cannot be shared across ranks");
  }
  MPI_Datatype piece_type = MPI_DATATYPE_NULL;
  MPI_Type_contiguous(static_cast<int>(piece), MPI_BYTE, &piece_type);
  MPI_Type_commit(&piece_type);
  std::vector<int> counts(static_cast<std::size_t>(size_));
  std::vector<int> offsets(static_cast<std::size_t>(size_));
  for (int r = 0; r < size_; ++r) {
    const cut_share o = error_cut_share(hier_, ranges_.piece_count(), static_cast<std::size_t>(r),
                                        static_cast<std::size_t>(size_));
    counts[static_cast<std::size_t>(r)] = static_cast<int>(o.piece_end - o.piece_begin);
    offsets[static_cast<std::size_t>(r)] = static_cast<int>(o.piece_begin);
  }
  MPI_Allgatherv(MPI_IN_PLACE, 0, MPI_DATATYPE_NULL,
                 ranges_.piece_bytes(0, ranges_.piece_count()).data(), counts.data(),
                 offsets.data(), piece_type, comm_);
  MPI_Type_free(&piece_type);
  scheduler::run_on_threads(threads, [&](const parallel_loop& loop, std::size_t) {
    ranges_.finish(loop);
    ranges_.finish_errors(loop);
  });
  built_ = true;
  walk_ = std::make_unique<error_cut_walk>(hier_, vol_, ranges_, isovalue_, share_.z_begin,
                                           share_.z_end);
  return true;
}

std::optional<double> distributed_cut::next_threshold(double floor, bool stop_now) {
  // Agreed on: the largest error waiting anywhere, and whether any rank must stop (one that
  // stopped alone would leave the others waiting in the next collective).
  double state[2] = {walk_ && !broken_ ? walk_->largest_waiting_error() : 0.0,
                     stop_now ? 1.0 : 0.0};
  allreduce_politely(state, 2, MPI_DOUBLE, MPI_MAX, comm_);
  if (!built_ || broken_ || state[1] > 0.0 || !(state[0] > floor)) return std::nullopt;
  return std::max(state[0] / 2, floor);
}

bool distributed_cut::round(double threshold, unsigned threads, const std::function<bool()>& stop) {
  int finished = 0;
  if (walk_ && !broken_) {
    scheduler::run_on_threads(threads, [&](const parallel_loop& loop, std::size_t) {
      finished = walk_->extend(threshold, loop, stop) ? 1 : 0;
    });
  }
  allreduce_politely(&finished, 1, MPI_INT, MPI_MIN, comm_);
  if (finished == 0) {
    broken_ = true;  // some rank stopped: the splits past the last round are not a round's
    return false;
  }
  committed_ = walk_->round_end();
  threshold_ = threshold;
  ++rounds_;
  return true;
}

void distributed_cut::gather() {
  const share_splits empty;
  const share_splits& all = walk_ ? walk_->splits() : empty;
  const std::size_t groups_end =
      committed_ == 0 ? 0
                      : all.splits[committed_ - 1].first_group + all.splits[committed_ - 1].groups;
  // A binomial tree rooted at the root: rank v (counted from the root) takes the bundles of
  // v + 1, v + 2, v + 4, … below its lowest set bit, then sends its own and theirs to v minus
  // that bit. The root receives log2(size) messages, not size − 1, and no rank more. The root's
  // own splits go into its piece directly, not through a bundle.
  const std::span<const share_split> own_splits =
      std::span<const share_split>(all.splits).subspan(sent_splits_, committed_ - sent_splits_);
  const std::span<const packed_group> own_groups =
      std::span<const packed_group>(all.groups).subspan(sent_groups_, groups_end - sent_groups_);
  std::vector<char> bundle;
  if (rank_ != root_) append_to_bundle(bundle, rank_, own_splits, own_groups);
  const int v = (rank_ - root_ + size_) % size_;
  for (int bit = 1; bit < size_; bit <<= 1) {
    if ((v & bit) != 0) {
      send_bytes(comm_, bundle.data(), bundle.size(), (v - bit + root_) % size_, tag_bundle);
      bundle.clear();
      bundle.shrink_to_fit();
      break;
    }
    if (v + bit < size_) {
      receive_bytes(
          comm_, (v + bit + root_) % size_, tag_bundle,
          [&bundle](const char* p, std::size_t n) { bundle.insert(bundle.end(), p, p + n); });
    }
  }
  if (rank_ == root_) {
    std::vector<std::pair<int, share_splits>> ranks = read_bundle(bundle, size_, root_);
    bundle = {};
    share_splits own;
    own.splits.assign(own_splits.begin(), own_splits.end());
    own.groups.assign(own_groups.begin(), own_groups.end());
    ranks.emplace_back(root_, std::move(own));
    if (ranks.size() != static_cast<std::size_t>(size_)) {
      throw error("the gather of splits reached the root with " + std::to_string(ranks.size()) +
                  " of " + std::to_string(size_) + " ranks");
    }
    std::sort(ranks.begin(), ranks.end(),
              [](const auto& a, const auto& b) { return a.first < b.first; });
    for (auto& [r, got] : ranks) {
      auto piece = std::make_shared<share_splits>(std::move(got));
      // The rank's group indices count from its first round; a piece's from its own start.
      std::uint64_t& base = groups_seen_[static_cast<std::size_t>(r)];
      for (share_split& sp : piece->splits) {
        if (sp.first_group < base || sp.first_group - base + sp.groups > piece->groups.size()) {
          throw error("rank " + std::to_string(r) + " sent a split whose groups it did not send");
        }
        sp.first_group -= base;
      }
      base += piece->groups.size();
      gathered_ += piece->splits.size();
      if (!piece->splits.empty()) pieces_.push_back(std::move(piece));
    }
  }
  sent_splits_ = committed_;
  sent_groups_ = groups_end;
}

void distributed_cut::restart(double isovalue) {
  isovalue_ = isovalue;
  walk_.reset();
  if (built_) {
    walk_ = std::make_unique<error_cut_walk>(hier_, vol_, ranges_, isovalue_, share_.z_begin,
                                             share_.z_end);
  }
  broken_ = false;
  threshold_ = std::numeric_limits<double>::infinity();
  rounds_ = 0;
  sent_splits_ = sent_groups_ = committed_ = 0;
  pieces_.clear();  // snapshots keep the pieces they show
  std::fill(groups_seen_.begin(), groups_seen_.end(), 0);
  gathered_ = 0;
}

triangle_mesh mesh_of_pieces(const hierarchy& hier, const volume& vol, double isovalue,
                             const cut_pieces& pieces, unsigned threads) {
  std::vector<const share_splits*> shares;
  shares.reserve(pieces.size());
  for (const auto& p : pieces) shares.push_back(p.get());
  triangle_mesh m;
  scheduler::run_on_threads(threads, [&](const parallel_loop& loop, std::size_t parts) {
    m = mesh_of_shares(hier, vol, isovalue, shares, loop, parts);
  });
  return m;
}

triangle_mesh distributed_cut::mesh(unsigned threads) const {
  return mesh_of_pieces(hier_, vol_, isovalue_, pieces_, threads);
}

}  // namespace progiso::detail
