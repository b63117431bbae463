// Label decluttering (label_declutter.hpp): hand layouts for priority, ties, touching edges and
// the previous-frame preference; seeded random layouts of thousands of labels checked by brute
// force (no two shown labels overlap, a hidden label overlaps a shown one of higher key, the
// result equals a plain O(n^2) greedy); moving labels: the shown set changes only when an
// overlap forces it, against a per-frame greedy without memory that flickers.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ostream>
#include <random>
#include <set>
#include <tuple>
#include <vector>

#include "terralod/blocks/label_declutter.hpp"

namespace {

namespace tb = terralod::blocks;
using Ids = std::set<tb::LabelId>;

tb::LabelCandidate label(std::int64_t id, float x, float y, float w, float h, double priority, float depth) {
  return {{0, id}, x, y, x + w, y + h, priority, depth};
}

}  // namespace
namespace terralod::blocks {
void PrintTo(const LabelId& id, std::ostream* os) { *os << id.layer << ":" << id.feature; }
}  // namespace terralod::blocks
namespace {

Ids one(std::int64_t feature) { return {tb::LabelId{0, feature}}; }

Ids to_set(std::span<const tb::LabelId> ids) { return {ids.begin(), ids.end()}; }

// The documented key, written independently: greater = placed first.
auto key_of(const tb::LabelCandidate& c, const Ids& previous) {
  return std::make_tuple(c.priority, previous.count(c.id) ? 1 : 0, -c.depth, -std::int64_t(c.id.layer),
                         -c.id.feature);
}

// The reference: sort by key, show a label unless it overlaps one shown before (O(n^2)).
std::vector<tb::LabelId> reference(const std::vector<tb::LabelCandidate>& cands, const Ids& previous) {
  std::vector<const tb::LabelCandidate*> order;
  for (const auto& c : cands) order.push_back(&c);
  std::sort(order.begin(), order.end(),
            [&](const auto* a, const auto* b) { return key_of(*a, previous) > key_of(*b, previous); });
  std::vector<const tb::LabelCandidate*> shown;
  for (const auto* c : order)
    if (std::none_of(shown.begin(), shown.end(), [&](const auto* s) { return tb::labels_overlap(*c, *s); }))
      shown.push_back(c);
  std::vector<tb::LabelId> out;
  for (const auto* s : shown) out.push_back(s->id);
  return out;
}

// Brute-force invariants of one frame: shown labels pairwise disjoint; every hidden label overlaps
// a shown label of higher key.
void check_frame(const std::vector<tb::LabelCandidate>& cands, const Ids& shown, const Ids& previous) {
  std::vector<const tb::LabelCandidate*> on;
  for (const auto& c : cands)
    if (shown.count(c.id)) on.push_back(&c);
  ASSERT_EQ(on.size(), shown.size());
  for (std::size_t i = 0; i < on.size(); ++i)
    for (std::size_t j = i + 1; j < on.size(); ++j)
      ASSERT_FALSE(tb::labels_overlap(*on[i], *on[j])) << on[i]->id.feature << " and " << on[j]->id.feature;
  for (const auto& c : cands) {
    if (shown.count(c.id)) continue;
    const bool blocked = std::any_of(on.begin(), on.end(), [&](const auto* s) {
      return tb::labels_overlap(c, *s) && key_of(*s, previous) > key_of(c, previous);
    });
    ASSERT_TRUE(blocked) << "label " << c.id.feature << " hidden without a reason";
  }
}

//   y 0 +-------A(5)------+              A [0,100)x[0,20) priority 5
//       |        +--------B(10)--------+ B [50,150)x[10,30) priority 10: wins over A
//  y 20 +--------|-------+             |C C [150,200)x[10,30) priority 1 touches B: shown
//       |        +---------------------+
TEST(LabelDeclutter, PriorityWinsAndTouchingEdgesDoNotOverlap) {
  tb::LabelDeclutterer d;
  const std::vector<tb::LabelCandidate> c = {
      label(1, 0, 0, 100, 20, 5, 10), label(2, 50, 10, 100, 20, 10, 900), label(3, 150, 10, 50, 20, 1, 10),
      label(4, 200, 30, 10, 10, 0, 1)};
  const auto shown = d.update(c);
  ASSERT_EQ(shown.size(), 3u);
  EXPECT_EQ(shown[0].feature, 2);  // placement order: priority 10, then 1, then 0
  EXPECT_EQ(shown[1].feature, 3);
  EXPECT_EQ(shown[2].feature, 4);  // touches C at a corner only
  EXPECT_EQ(d.stats().candidates, 4u);
  EXPECT_EQ(d.stats().shown, 3u);
}

TEST(LabelDeclutter, TiesGoToTheNearerThenTheSmallerId) {
  tb::LabelDeclutterer d;
  EXPECT_EQ(to_set(d.update(std::vector{label(1, 0, 0, 50, 10, 3, 200), label(2, 10, 5, 50, 10, 3, 100)})),
            one(2));  // nearer
  d.reset();
  EXPECT_EQ(to_set(d.update(std::vector{label(9, 0, 0, 50, 10, 3, 100), label(7, 10, 5, 50, 10, 3, 100)})),
            one(7));  // same depth: smaller id
}

TEST(LabelDeclutter, AShownLabelKeepsItsPlaceAgainstAnEqualNewcomerNotAHigherOne) {
  tb::LabelDeclutterer d;
  const auto a = label(1, 100, 100, 80, 16, 2, 500);
  EXPECT_EQ(to_set(d.update(std::vector{a})), one(1));
  // B appears, nearer, same priority, overlapping A: A stays (it was shown), B waits.
  const auto b = label(2, 120, 104, 80, 16, 2, 50);
  EXPECT_EQ(to_set(d.update(std::vector{a, b})), one(1));
  EXPECT_EQ(d.stats().kept, 1u);
  EXPECT_EQ(to_set(d.update(std::vector{b, a})), one(1));  // and frame after frame
  // Without memory (a cut), the nearer one wins.
  d.reset();
  EXPECT_EQ(to_set(d.update(std::vector{a, b})), one(2));
  // C of higher priority displaces the shown B.
  const auto c = label(3, 185, 104, 10, 16, 2.5, 900);                       // overlaps B only
  EXPECT_EQ(to_set(d.update(std::vector{a, b, c})), (Ids{{0, 1}, {0, 3}}));  // A no longer blocked by B
  // A label off the screen (the caller culls) still takes part consistently.
  EXPECT_EQ(
      to_set(d.update(std::vector{label(5, -500, -500, 40, 40, 1, 1), label(6, -480, -480, 5, 5, 0, 1)})),
      one(5));
}

std::vector<tb::LabelCandidate> random_layout(std::mt19937& rng, int n) {
  std::uniform_real_distribution<float> x(-60.0f, 1280.0f), y(-20.0f, 720.0f), w(20.0f, 140.0f),
      h(10.0f, 22.0f), depth(10.0f, 30000.0f);
  std::uniform_int_distribution<int> prio(0, 4), layer(0, 2);  // many ties
  std::vector<tb::LabelCandidate> out;
  for (int i = 0; i < n; ++i) {
    const float x0 = x(rng), y0 = y(rng);
    out.push_back(
        {{std::uint32_t(layer(rng)), i}, x0, y0, x0 + w(rng), y0 + h(rng), double(prio(rng)), depth(rng)});
  }
  return out;
}

TEST(LabelDeclutter, RandomLayoutsNeverOverlapAndMatchTheGreedyReference) {
  const unsigned seed = 20261202;
  std::printf("seed %u\n", seed);
  std::mt19937 rng(seed);
  // Keys: integer priorities and depths in steps of 1000 m (the 64-bit radix path, many full
  // ties broken by id); priorities k + 0.1, not floats (the compared 128-bit path); negative depths
  // (the compared path too).
  enum class Keys { TiesPacked, DoublePriorities, NegativeDepths };
  for (const Keys keys : {Keys::TiesPacked, Keys::DoublePriorities, Keys::NegativeDepths})
    for (int cell : {1, 32, 200}) {
      tb::LabelDeclutterer d({.screen_width = 1280, .screen_height = 720, .cell_px = cell});
      Ids previous;  // what d showed in its previous update
      std::vector<tb::LabelCandidate> cands;
      for (int frame = 0; frame < 3; ++frame) {
        if (frame < 2) {
          cands = random_layout(rng, cell == 1 ? 1000 : 3000);
          for (auto& c : cands) {
            if (keys == Keys::TiesPacked) c.depth = 1000.0f * std::round(c.depth / 1000.0f);
            if (keys == Keys::DoublePriorities) c.priority += 0.1;
            if (keys == Keys::NegativeDepths) c.depth -= 15000.0f;
          }
        } else {  // frame 1's labels moved a little: the previous frame matters
          for (auto& c : cands) c.x0 += 0.5f, c.x1 += 0.5f;
        }
        const auto span = d.update(cands);
        const std::vector<tb::LabelId> got(span.begin(), span.end());
        const Ids shown = to_set(got);
        ASSERT_EQ(shown.size(), got.size()) << "an id shown twice";
        check_frame(cands, shown, previous);
        EXPECT_EQ(got, reference(cands, previous))
            << "keys " << int(keys) << " cell " << cell << " frame " << frame;
        EXPECT_GT(shown.size(), 100u);
        EXPECT_LT(shown.size(), cands.size());
        previous = shown;
      }
    }
}

// Each frame's candidates for `frames` frames: labels drifting by < 1 px per frame, depths
// jittering (a camera shaking at the same distance), equal priorities in three classes.
std::vector<std::vector<tb::LabelCandidate>> drifting(unsigned seed, int n, int frames) {
  std::mt19937 rng(seed);
  std::vector<tb::LabelCandidate> base = random_layout(rng, n);
  std::uniform_real_distribution<float> v(-0.9f, 0.9f), jitter(-30.0f, 30.0f);
  std::vector<std::pair<float, float>> vel;
  for (std::size_t i = 0; i < base.size(); ++i) vel.push_back({v(rng), v(rng)});
  std::vector<std::vector<tb::LabelCandidate>> out;
  for (int f = 0; f < frames; ++f) {
    std::vector<tb::LabelCandidate> frame = base;
    for (std::size_t i = 0; i < frame.size(); ++i) {
      const float dx = vel[i].first * float(f), dy = vel[i].second * float(f);
      frame[i].x0 += dx, frame[i].x1 += dx, frame[i].y0 += dy, frame[i].y1 += dy;
      frame[i].depth = 1000.0f + jitter(rng);  // all labels at about the same distance
    }
    out.push_back(std::move(frame));
  }
  return out;
}

struct FlickerCount {
  std::size_t changes = 0;   // labels appearing or disappearing between frames
  std::size_t unforced = 0;  // labels hidden without a shown label of higher priority, or of
                             // equal priority that was shown the frame before, overlapping them
};

FlickerCount run(const std::vector<std::vector<tb::LabelCandidate>>& frames, bool memory) {
  tb::LabelDeclutterer d;
  FlickerCount out;
  Ids before;
  for (std::size_t f = 0; f < frames.size(); ++f) {
    if (!memory) d.reset();  // the naive per-frame greedy
    const Ids now = to_set(d.update(frames[f]));
    if (f > 0) {
      std::vector<tb::LabelId> diff;
      std::set_symmetric_difference(before.begin(), before.end(), now.begin(), now.end(),
                                    std::back_inserter(diff));
      out.changes += diff.size();
      for (const auto& c : frames[f]) {
        if (!before.count(c.id) || now.count(c.id)) continue;  // only labels that disappeared
        const bool forced = std::any_of(frames[f].begin(), frames[f].end(), [&](const tb::LabelCandidate& s) {
          return now.count(s.id) && tb::labels_overlap(c, s) &&
                 (s.priority > c.priority || (s.priority == c.priority && before.count(s.id)));
        });
        if (!forced) ++out.unforced;
      }
    }
    before = now;
  }
  return out;
}

TEST(LabelDeclutter, MovingLabelsDoNotFlicker) {
  const unsigned seed = 19;
  std::printf("seed %u\n", seed);
  const auto frames = drifting(seed, 2000, 60);
  const FlickerCount with = run(frames, /*memory=*/true), without = run(frames, /*memory=*/false);
  std::printf(
      "60 frames of 2000 drifting labels: %zu shown-set changes with memory (%zu unforced), %zu "
      "without (%zu unforced)\n",
      with.changes, with.unforced, without.changes, without.unforced);
  EXPECT_EQ(with.unforced, 0u);       // every disappearance is forced by an overlap
  EXPECT_GT(without.unforced, 100u);  // the naive greedy swaps labels as their depths jitter
  EXPECT_LT(with.changes * 5, without.changes);
  EXPECT_GT(with.changes, 0u);  // the labels do run into each other
}

}  // namespace
