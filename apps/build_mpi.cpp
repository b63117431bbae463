// terralod build under MPI (see build_mpi.hpp).
#include "build_mpi.hpp"

#include <mpi.h>

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>
#include <thread>
#include <vector>

#include "terralod/pm/byte_io.hpp"
#include "terralod/pm/parallel.hpp"

namespace terralod::cli {
namespace {

// Protocol, per worker thread ("slot") s of rank r >= 1, on tag s + 1 between r and 0:
//   r -> 0  READY (one byte)        then, after each block,  r -> 0  the block (below)
//   0 -> r  key (two int32: col, row) of the next block to build, or an empty message: stop.
// A block (blocks::BuiltBlock, as build_block makes it), in pm/byte_io.hpp's little-endian
// codec whatever the ranks' byte order: i32 col, row; f64 base error; u64 vertices; u32 summary
// record bytes S; the S bytes; the encoded PM (the rest). Rank 0 serves every slot from one
// thread (RemoteBuilder), receiving from any rank; it writes what it gets.
constexpr int kReady = 0x52;

std::vector<std::uint8_t> encode_block(const blocks::BuiltBlock& b) {
  pm::ByteWriter w;
  w.bytes.reserve(28 + b.summary.size() + b.pm.size());
  w.i32(b.key.col), w.i32(b.key.row);
  w.f64(b.base_error);
  w.u64(b.vertices);
  w.u32(std::uint32_t(b.summary.size()));
  w.raw(b.summary);
  w.raw(b.pm);
  return std::move(w.bytes);
}

blocks::BuiltBlock decode_block(const std::vector<std::uint8_t>& m, int from) {
  pm::ByteReader r(m, [&](const pm::ByteReadFailure& f) {
    throw blocks::BuildError("a message of " + std::to_string(m.size()) + " bytes from rank " +
                             std::to_string(from) + " is not a block: truncated " + f.what + " at byte " +
                             std::to_string(f.position));
  });
  blocks::BuiltBlock b;
  b.key.col = r.i32("block key"), b.key.row = r.i32("block key");
  b.base_error = r.f64("base error");
  b.vertices = r.u64("vertex count");
  const auto summary = r.raw(r.u32("summary size"), "summary record");
  b.summary.assign(summary.begin(), summary.end());
  const auto pm = r.raw(r.left(), "progressive mesh");
  b.pm.assign(pm.begin(), pm.end());
  return b;
}

/// A message from (source, tag), waiting without spinning: Open MPI's blocking receive polls,
/// which would take a core from the builders on an oversubscribed machine.
std::vector<std::uint8_t> receive(int source, int tag, int* from = nullptr, int* tag_out = nullptr) {
  MPI_Message msg;
  MPI_Status st;
  for (int flag = 0;;) {
    MPI_Improbe(source, tag, MPI_COMM_WORLD, &flag, &msg, &st);
    if (flag) break;
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  int n = 0;
  MPI_Get_count(&st, MPI_BYTE, &n);
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(n));
  MPI_Mrecv(bytes.data(), n, MPI_BYTE, &msg, MPI_STATUS_IGNORE);
  if (from) *from = st.MPI_SOURCE;
  if (tag_out) *tag_out = st.MPI_TAG;
  return bytes;
}

void send(int dest, int tag, const void* data, std::size_t n) {
  MPI_Send(data, int(n), MPI_BYTE, dest, tag, MPI_COMM_WORLD);
}

[[noreturn]] void abort_job(int rank, const std::string& what) {
  std::fprintf(stderr, "terralod build (rank %d): %s\n", rank, what.c_str());
  std::fflush(stderr);
  MPI_Abort(MPI_COMM_WORLD, 1);
  std::exit(1);
}

/// Rank 0's side: serves every slot of every other rank. slots[r] = threads of rank r.
blocks::RemoteBuilder serve_ranks(std::vector<int> slots) {
  return [slots](const std::function<std::optional<blocks::BlockKey>()>& claim,
                 const std::function<void(blocks::BuiltBlock)>& deliver) {
    int open = 0;
    for (int s : slots) open += s;
    while (open > 0) {
      int from = 0, tag = 0;
      const std::vector<std::uint8_t> m = receive(MPI_ANY_SOURCE, MPI_ANY_TAG, &from, &tag);
      if (!(m.size() == 1 && m[0] == kReady)) deliver(decode_block(m, from));
      if (const std::optional<blocks::BlockKey> k = claim()) {
        pm::ByteWriter key;
        key.i32(k->col), key.i32(k->row);
        send(from, tag, key.bytes.data(), key.bytes.size());
      } else {
        send(from, tag, nullptr, 0);
        --open;
      }
    }
  };
}

/// A rank >= 1: `threads` slots, each asking rank 0 for a block, building it and sending it back.
void work_for_rank0(const blocks::DemSource& src, const blocks::DatabaseBuildOptions& opt, int threads,
                    int rank) {
  std::vector<std::thread> pool;
  for (int s = 0; s < threads; ++s)
    pool.emplace_back([&, s] {
      try {
        const int tag = s + 1;
        const char ready = char(kReady);
        send(0, tag, &ready, 1);
        for (;;) {
          const std::vector<std::uint8_t> m = receive(0, tag);
          if (m.empty()) break;
          pm::ByteReader r(m, [&](const pm::ByteReadFailure& f) {
            throw blocks::BuildError("a message of " + std::to_string(m.size()) +
                                     " bytes from rank 0 is not a block key: truncated " + f.what);
          });
          blocks::BlockKey key;
          key.col = r.i32("block key"), key.row = r.i32("block key");
          const std::vector<std::uint8_t> out = encode_block(blocks::build_block(src, key, opt));
          send(0, tag, out.data(), out.size());
        }
      } catch (const std::exception& e) {
        abort_job(rank, e.what());
      }
    });
  for (auto& t : pool) t.join();
}

}  // namespace

int build_with_mpi(
    const std::function<std::unique_ptr<blocks::DemSource>()>& open, const std::string& out,
    blocks::DatabaseBuildOptions opt,
    const std::function<void(const blocks::DatabaseSummary&, int ranks, const blocks::DemSource&)>& report) {
  int provided = 0;
  MPI_Init_thread(nullptr, nullptr, MPI_THREAD_MULTIPLE, &provided);
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  if (provided < MPI_THREAD_MULTIPLE)
    abort_job(rank, "the MPI library gives no MPI_THREAD_MULTIPLE, which the build's threads need");
  const int threads = terralod::pm::thread_count(opt.threads);
  try {
    const std::unique_ptr<blocks::DemSource> src = open();
    // Every rank says how many threads it builds with; rank 0 hands out one block per thread.
    std::vector<int> slots(std::size_t(size), 0);
    MPI_Gather(&threads, 1, MPI_INT, slots.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
    if (rank == 0) {
      slots[0] = 0;
      opt.remote_builders.push_back(serve_ranks(slots));
      const blocks::DatabaseSummary s = blocks::build_database(*src, out, opt);
      report(s, size, *src);
    } else {
      // Progress and the summary are rank 0's.
      opt.progress = nullptr;
      work_for_rank0(*src, opt, threads, rank);
    }
  } catch (const std::exception& e) {
    abort_job(rank, e.what());
  }
  MPI_Finalize();
  return 0;
}

}  // namespace terralod::cli
