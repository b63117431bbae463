// Background block loader thread: read, decode, build the collapse DAG; see block_loader.hpp.
#include "terralod/blocks/block_loader.hpp"

#include <pthread.h>

#include <algorithm>
#include <cassert>
#include <chrono>
#include <stdexcept>

#include "terralod/pm/pm_io.hpp"
#include "terralod/pm/timing.hpp"

namespace terralod::blocks {

namespace {
using pm::ms_since;
std::string block_name(BlockKey k) {
  return "block (" + std::to_string(k.col) + "," + std::to_string(k.row) + ")";
}
// LoadedBlock::memory_bytes: the block with its DAG and a full-resolution refinement.
std::size_t reserved_bytes(const pm::CollapseDag& dag, const pm::RefinementOptions& refinement) {
  return sizeof(LoadedBlock) + dag.memory_bytes() +
         pm::SelectiveRefinement::full_memory_bytes(dag, refinement);
}
}  // namespace

std::shared_ptr<const LoadedBlock> decode_block(const BlockGrid& grid, BlockKey k,
                                                std::span<const std::uint8_t> blob,
                                                const std::string& source_name, double floor_m,
                                                const pm::RefinementOptions& refinement) {
  assert(grid.contains(k));
  const std::string name = source_name + ": " + block_name(k);
  const auto t = std::chrono::steady_clock::now();
  auto b = std::make_shared<LoadedBlock>();
  b->key = k;
  {
    const pm::ProgressiveMesh pm = pm::decode_pm(blob, name);
    const SampleRect d = grid.domain(k);
    const pm::Heightfield& hf = pm.heightfield();
    if (hf.width() != d.width() || hf.height() != d.height())
      throw DatabaseError(source_name, block_name(k) + ": " + std::to_string(hf.width()) + " x " +
                                           std::to_string(hf.height()) + " samples, the block grid expects " +
                                           std::to_string(d.width()) + " x " + std::to_string(d.height()));
    b->metric = pm.metric();
    b->dag = std::make_unique<pm::CollapseDag>(
        pm, pm::DagOptions{.skip = floor_m > 0 ? pm::CollapseDag::skip_for_floor(pm, floor_m) : 0});
  }
  b->blob_bytes = blob.size();
  b->memory_bytes = reserved_bytes(*b->dag, refinement);
  b->decode_ms = ms_since(t);
  return b;
}

BlockLoader::BlockLoader(BlockSourceFactory factory, const BlockGrid& grid, PrepareFn prepare, int threads)
    : factory_(std::move(factory)), grid_(grid), prepare_(std::move(prepare)) {
  if (threads < 1) throw std::invalid_argument("BlockLoader: threads must be >= 1");
  // Started last: every member the threads read exists. Each opens its source first; waiting
  // for them makes held_bytes() (their caches' bound) the same from the first frame on.
  for (int i = 0; i < threads; ++i) threads_.emplace_back([this] { run(); });
  std::unique_lock lock(mutex_);
  cv_.wait(lock, [&] { return opened_ == threads; });
}

BlockLoader::~BlockLoader() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  cv_.notify_all();
  for (std::thread& t : threads_) t.join();
}

void BlockLoader::set_queue(std::vector<Request> requests) {
  std::stable_sort(requests.begin(), requests.end(),
                   [](const Request& a, const Request& b) { return a.priority < b.priority; });
  std::vector<Request> unique;
  unique.reserve(requests.size());
  for (const Request& r : requests) {
    assert(grid_.contains(r.key));
    if (std::none_of(unique.begin(), unique.end(), [&](const Request& u) { return u.key == r.key; }))
      unique.push_back(r);
  }
  {
    std::lock_guard lock(mutex_);
    // Not again what is being read or finished and not yet taken.
    std::erase_if(unique, [&](const Request& r) {
      return std::find(in_flight_.begin(), in_flight_.end(), r.key) != in_flight_.end() ||
             std::any_of(results_.begin(), results_.end(),
                         [&](const LoadResult& x) { return x.key == r.key; });
    });
    queue_ = std::move(unique);
  }
  cv_.notify_all();
}

std::vector<LoadResult> BlockLoader::take_results() {
  std::lock_guard lock(mutex_);
  std::vector<LoadResult> out;
  out.swap(results_);
  return out;
}

bool BlockLoader::busy(BlockKey k) const {
  std::lock_guard lock(mutex_);
  if (std::find(in_flight_.begin(), in_flight_.end(), k) != in_flight_.end()) return true;
  return std::any_of(queue_.begin(), queue_.end(), [&](const Request& r) { return r.key == k; });
}

bool BlockLoader::holds(BlockKey k) const {
  std::lock_guard lock(mutex_);
  return std::find(in_flight_.begin(), in_flight_.end(), k) != in_flight_.end() ||
         std::any_of(results_.begin(), results_.end(), [&](const LoadResult& r) { return r.key == k; });
}

std::size_t BlockLoader::pending() const {
  std::lock_guard lock(mutex_);
  return queue_.size() + in_flight_.size();
}

std::size_t BlockLoader::finished() const {
  std::lock_guard lock(mutex_);
  return results_.size();
}

std::uint64_t BlockLoader::bytes_read() const {
  std::lock_guard lock(mutex_);
  return bytes_read_;
}

std::size_t BlockLoader::held_bytes() const {
  std::lock_guard lock(mutex_);
  std::size_t n = in_flight_bytes_ + source_bytes_;
  for (const LoadResult& r : results_) n += r.block ? r.block->memory_bytes : 0;
  return n;
}

void BlockLoader::run() {
  pthread_setname_np(pthread_self(), "terralod-loader");  // for profilers and debuggers
  std::unique_ptr<BlockSource> source;
  std::string open_error;
  try {
    source = factory_();
  } catch (const std::exception& e) {
    open_error = e.what();
  }
  const std::size_t source_bytes = source ? source->memory_bytes() : 0;
  std::unique_lock lock(mutex_);
  source_bytes_ += source_bytes;
  ++opened_;
  cv_.notify_all();
  for (;;) {
    cv_.wait(lock, [&] { return stop_ || !queue_.empty(); });
    if (stop_) return;
    const BlockKey k = queue_.front().key;
    const double floor_m = queue_.front().floor_m;
    const std::size_t planned = queue_.front().bytes;
    queue_.erase(queue_.begin());
    in_flight_.push_back(k);
    in_flight_bytes_ += planned;
    lock.unlock();
    LoadResult r;
    r.key = k;
    std::size_t bytes = 0;
    if (!source) {
      r.error = open_error;
    } else {
      try {
        const auto t = std::chrono::steady_clock::now();
        const std::vector<std::uint8_t> blob = source->read(k);
        const double read_ms = ms_since(t);
        bytes = blob.size();
        auto b = std::const_pointer_cast<LoadedBlock>(decode_block(grid_, k, blob, source->name(), floor_m));
        b->read_ms = read_ms;
        if (prepare_) r.selection = prepare_(*b);
        if (r.selection)  // reserved for the options the refinement was made with
          b->memory_bytes = reserved_bytes(*b->dag, r.selection->options());
        r.block = std::move(b);
      } catch (const std::exception& e) {
        r.error = e.what();
        if (r.error.empty()) r.error = source->name() + ": " + block_name(k) + ": unknown error";
      }
    }
    lock.lock();
    in_flight_.erase(std::find(in_flight_.begin(), in_flight_.end(), k));
    in_flight_bytes_ -= planned;
    bytes_read_ += bytes;
    results_.push_back(std::move(r));
  }
}

}  // namespace terralod::blocks
