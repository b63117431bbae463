// libFuzzer target for the approximation-tree decoder: decode_tree on arbitrary bytes must
// either throw TreeFormatError or give a tree that re-encodes to the same bytes and keeps the
// structural contract (dense ids, parents before children, child domains inside the grid).
//
// Every input is decoded twice: as given (magic, version and checksum checks) and with its
// CRC-32 trailer patched to be right, so that mutations reach the node records. Bounded work:
// the decoder checks every count against the bytes left, so one run is O(input size).
#include <zlib.h>

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "fuzz_support.hpp"
#include "terralod/blocks/approximation_tree.hpp"

namespace {

namespace tb = terralod::blocks;

void check(std::span<const std::uint8_t> bytes) {
  tb::ApproximationTree tree;
  try {
    tree = tb::decode_tree(bytes, "fuzz");
  } catch (const tb::TreeFormatError&) {
    return;
  }
  const auto& p = tree.parameters();
  for (const tb::TreeNode& n : tree.nodes()) {
    if (n.id != 0 && (n.parent < 0 || n.parent >= n.id))
      terralod::fuzz::finding("fuzz_tree_decoder", "bad parent");
    if (n.domain.col0 < 0 || n.domain.col1 >= std::max(1, p.grid_width) || n.domain.col0 > n.domain.col1)
      terralod::fuzz::finding("fuzz_tree_decoder", "domain outside the grid");
    for (const auto& t : n.surface.triangles)
      for (std::uint32_t v : t)
        if (v >= n.surface.points.size())
          terralod::fuzz::finding("fuzz_tree_decoder", "triangle index out of range");
  }
  if (tb::encode_tree(tree) != std::vector<std::uint8_t>(bytes.begin(), bytes.end()))
    terralod::fuzz::finding("fuzz_tree_decoder", "decoded tree does not re-encode to the same bytes");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  check({data, size});
  if (size >= 16) {
    std::vector<std::uint8_t> fixed(data, data + size);
    const std::uint32_t crc = std::uint32_t(crc32(0L, fixed.data(), uInt(size - 4)));
    for (int i = 0; i < 4; ++i) fixed[size - 4 + std::size_t(i)] = std::uint8_t(crc >> (8 * i));
    check(fixed);
  }
  return 0;
}
