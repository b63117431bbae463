// Label decluttering (issue 19, point 3): from the labels that could be drawn this frame, the
// ones shown so that no two overlap on screen, the higher priority wins, and a label shown in the
// previous frame is not replaced by an equal one that appears (no flicker). Greedy placement in
// key order over a uniform screen grid; memory reused from frame to frame.
//
// Usage:
//   namespace tb = terralod::blocks;
//   tb::LabelDeclutterer declutter({.screen_width = 1280, .screen_height = 720});
//   every frame:
//     candidates.clear();
//     for (each label in view) candidates.push_back({{layer, feature_id}, x0, y0, x1, y1, priority, depth});
//     for (const tb::LabelId& id : declutter.update(candidates)) draw(id);
//
// Contract:
//   candidate  id: stable from frame to frame (layer index + feature id; unique within a
//              frame (two shown labels with one id are asserted). Rectangle [x0, x1) x [y0, y1) in pixels,
//              x0 < x1 and y0 < y1 (a label has an area), finite (asserted); it may lie partly or wholly off
//              the screen (the caller culls; off-screen parts are binned at the border). priority: any finite
//              double, higher wins (ObjectRules::priority). depth: distance from the camera (any finite
//              value; nearer = smaller wins ties).
//   overlap    half-open rectangles: two labels overlap when their interiors meet,
//              a.x0 < b.x1 && b.x0 < a.x1 && a.y0 < b.y1 && b.y0 < a.y1. Labels that only touch
//              along an edge or at a corner do not overlap.
//   order      candidates are placed greedily in decreasing key: the key is (priority, shown in
//              the previous update, -depth, -id) compared in that order, so a higher priority
//              always wins; at equal priority a label shown in the previous frame wins over one
//              that was not (the no-flicker rule: a newcomer of equal priority never displaces a
//              shown label; one of higher priority does); then nearer wins, then the smaller id.
//              A candidate is shown if and only if it overlaps no candidate shown before it.
//              Hence: shown labels never overlap, and a label is hidden only if it overlaps a
//              shown label of higher key. With equal priorities a shown label stays shown
//              until a label that was also shown comes to overlap it (both moved), whatever
//              newcomers appear; only then does the nearer one win.
//   update     returns the ids shown, in placement order (decreasing key); the span stays valid
//              until the next update. The previous frame is the previous call's result; reset()
//              forgets it (a cut in the view).
//   cost       O(n log n) for n candidates: a hash lookup per candidate among the previous
//              frame's ids (open addressing); the key order by an LSD radix sort of 64-bit keys
//              (8 passes) when every priority is exactly a float and every depth >= 0, else by
//              std::sort of 128-bit keys (the same order); ties of the whole key by id. Then the
//              grid cells each rectangle covers (Options::cell_px, default 32: a 100 x 16 px
//              label covers 4 to 8 cells), each holding copies of the shown rectangles in it.
//              No allocation once the buffers have grown to the largest frame seen.
//   memory     about 80 bytes per candidate of the largest frame, plus one vector per grid cell
//              (920 cells at 1280 x 720) of 16 bytes per shown rectangle in it.
#pragma once

#include <compare>
#include <cstdint>
#include <span>
#include <vector>

namespace terralod::blocks {

/// A label's identity across frames: its layer (index in the caller's list) and feature id.
struct LabelId {
  std::uint32_t layer = 0;
  std::int64_t feature = 0;
  auto operator<=>(const LabelId&) const = default;
};

struct LabelCandidate {
  LabelId id;
  float x0 = 0, y0 = 0, x1 = 0, y1 = 0;  ///< screen rectangle [x0, x1) x [y0, y1), pixels
  double priority = 0.0;                 ///< higher wins
  float depth = 0.0f;                    ///< distance from the camera; nearer wins ties
};

/// True when the interiors of the two rectangles meet (touching edges do not overlap).
inline bool labels_overlap(const LabelCandidate& a, const LabelCandidate& b) {
  return a.x0 < b.x1 && b.x0 < a.x1 && a.y0 < b.y1 && b.y0 < a.y1;
}

/// The screen the labels are placed on (outside the class: GCC cannot take a nested struct
/// with default member initialisers as a default argument).
struct LabelDeclutterOptions {
  int screen_width = 1280, screen_height = 720;  ///< pixels, >= 1 (asserted)
  int cell_px = 32;                              ///< grid cell side, pixels, >= 1 (asserted)
};

class LabelDeclutterer {
 public:
  using Options = LabelDeclutterOptions;
  struct Stats {
    std::size_t candidates = 0, shown = 0;
    std::size_t kept = 0;           ///< shown now and in the previous update
    std::size_t overlap_tests = 0;  ///< rectangle pairs compared
  };

  explicit LabelDeclutterer(Options options = {});  ///< remembers no previous frame

  /// One frame: the ids of the labels shown (see the contract).
  std::span<const LabelId> update(std::span<const LabelCandidate> candidates);
  /// Forgets the previous frame (the next update prefers no label).
  void reset();
  /// Counts of the last update.
  const Stats& stats() const { return stats_; }

 private:
  struct Key {
    std::uint64_t major, minor;  // priority; previous-frame flag and depth, order-preserving bits
    std::uint32_t index;         // into the candidates
  };
  struct Packed {
    std::uint64_t key;  // the key in 64 bits, when priorities are floats and depths >= 0
    std::uint32_t index;
  };
  std::size_t slot_of(const LabelId& id) const;
  bool was_shown(const LabelId& id) const;
  void remember(std::span<const LabelId> ids);             // the ids shown, for the next update
  void order(std::span<const LabelCandidate> candidates);  // fills order_ and shown_before_

  Options options_;
  int cols_ = 0, rows_ = 0;
  std::vector<Key> keys_;
  std::vector<Packed> packed_, packed_tmp_;
  std::vector<std::uint32_t> order_;        // candidate indices in decreasing key
  std::vector<std::uint8_t> shown_before_;  // per candidate: shown in the previous update
  struct Box {
    float x0, y0, x1, y1;
  };
  std::vector<std::vector<Box>> cells_;    // rectangles of the shown labels per cell (copies: no
                                           // indirection into the candidates)
  std::vector<std::uint32_t> used_cells_;  // cells to clear before the next update
  std::vector<LabelId> shown_;
  std::vector<LabelId> slots_;      // hash set of the ids shown by the previous update
  std::vector<std::uint8_t> full_;  // per slot: holds an id
  Stats stats_;
};

}  // namespace terralod::blocks
