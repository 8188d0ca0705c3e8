#include "gissar/render/heightfield.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <memory>
#include <utility>

#include "gissar/scene/triangle_mesh.h"
#include "gissar/util/check.h"

namespace gissar::render {

HeightfieldTree::HeightfieldTree(const Eigen::Vector3f* posts, int width, int height,
                                 const std::vector<uint8_t>* cells)
    : posts_(posts), width_(width), height_(height) {
  GISSAR_CHECK(width >= 2 && height >= 2);
  if (cells != nullptr) {
    const size_t count = size_t(width - 1) * (height - 1);
    GISSAR_CHECK(cells->size() == count);
    masked_ = true;
    cell_bits_.assign((count + 63) / 64, 0);
    for (size_t k = 0; k < count; ++k) {
      if ((*cells)[k] != 0) cell_bits_[k >> 6] |= uint64_t{1} << (k & 63);
    }
    rank_before_.resize(cell_bits_.size() + 1);
    uint32_t total = 0;
    for (size_t w = 0; w < cell_bits_.size(); ++w) {
      rank_before_[w] = total;
      total += uint32_t(__builtin_popcountll(cell_bits_[w]));
    }
    rank_before_.back() = total;
  }
  column_cross_row_up_ = scene::GridColumnCrossRowUp(posts, width);
  const int cells_x = width - 1, cells_y = height - 1;
  levels_.resize(kTileLevel);
  for (int k = 1; k <= kTileLevel; ++k) {
    Level& level = levels_[k - 1];
    const int side = 1 << k;
    level.nx = (cells_x + side - 1) / side;
    level.ny = (cells_y + side - 1) / side;
  }
  auto empty = [](Box& box) {
    for (int a = 0; a < 3; ++a) {
      box.lower[a] = std::numeric_limits<float>::infinity();
      box.upper[a] = -std::numeric_limits<float>::infinity();
    }
  };
  auto grow = [](Box& box, const float lower[3], const float upper[3]) {
    for (int a = 0; a < 3; ++a) {
      box.lower[a] = std::min(box.lower[a], lower[a]);
      box.upper[a] = std::max(box.upper[a], upper[a]);
    }
  };
  // Level 1 from the posts (a node of 2 x 2 cells spans up to 3 x 3 posts),
  // computed where level 2 needs it (no array of level-1 boxes: at 4000^2
  // posts it would be 96 MB of fresh pages).
  static_assert(kTileLevel >= 2);
  std::atomic<bool> non_finite{false};
  auto level1_box = [&](int i, int j) {
    Box box;
    empty(box);
    auto add_post = [&](int r, int c) {
      const Eigen::Vector3f& p = posts[size_t(r) * width + c];
      if (p.allFinite()) {
        grow(box, p.data(), p.data());
      } else {
        non_finite = true;
      }
    };
    if (!masked_) {
      for (int r = 2 * j; r <= std::min(2 * j + 2, height - 1); ++r) {
        for (int c = 2 * i; c <= std::min(2 * i + 2, width - 1); ++c) add_post(r, c);
      }
      return box;
    }
    // With holes: the posts of the cells in only.
    for (int r = 2 * j; r <= std::min(2 * j + 1, height - 2); ++r) {
      for (int c = 2 * i; c <= std::min(2 * i + 1, width - 2); ++c) {
        if (!Included(size_t(r) * (width - 1) + c)) continue;
        for (int dr = 0; dr < 2; ++dr) {
          for (int dc = 0; dc < 2; ++dc) add_post(r + dr, c + dc);
        }
      }
    }
    return box;
  };
  // Each higher level: its nodes' children in groups, and its own boxes
  // (every element written by the loop: no zero-filling pass).
  std::unique_ptr<Box[]> below;  // the boxes of the level below (from level 2 on)
  for (int k = 2; k <= kTileLevel; ++k) {
    const int below_nx = levels_[k - 2].nx, below_ny = levels_[k - 2].ny;
    Level& level = levels_[k - 1];
    level.groups.resize(size_t(level.nx) * level.ny);
    std::unique_ptr<Box[]> boxes = std::make_unique_for_overwrite<Box[]>(level.groups.size());
    tbb::parallel_for(tbb::blocked_range<int>(0, level.ny, 16), [&](const tbb::blocked_range<int>& rows) {
      for (int j = rows.begin(); j < rows.end(); ++j) {
        for (int i = 0; i < level.nx; ++i) {
          Group& group = level.groups[size_t(j) * level.nx + i];
          Box& box = boxes[size_t(j) * level.nx + i];
          empty(box);
          for (int q = 0; q < 4; ++q) {
            const int ci = 2 * i + (q & 1), cj = 2 * j + (q >> 1);
            Box child;
            empty(child);
            if (ci < below_nx && cj < below_ny) {
              child = k == 2 ? level1_box(ci, cj) : below[size_t(cj) * below_nx + ci];
            }
            for (int a = 0; a < 3; ++a) {
              group.lower[a][q] = child.lower[a];
              group.upper[a][q] = child.upper[a];
            }
            grow(box, child.lower, child.upper);
          }
        }
      }
    });
    below = std::move(boxes);
  }
  all_finite_ = !non_finite;
  for (size_t k = 0; k < levels_[kTileLevel - 1].groups.size(); ++k) {
    if (below[k].lower[0] <= below[k].upper[0]) {
      tiles_.push_back(uint32_t(k));
      tile_boxes_.push_back(below[k]);
    }
  }
}

void HeightfieldTree::TileBounds(size_t tile, float lower[3], float upper[3]) const {
  const Box& box = tile_boxes_[tile];
  for (int a = 0; a < 3; ++a) {
    lower[a] = box.lower[a];
    upper[a] = box.upper[a];
  }
}

size_t HeightfieldTree::MemoryBytes() const {
  size_t bytes = tiles_.capacity() * sizeof(uint32_t) + tile_boxes_.capacity() * sizeof(Box) +
                 cell_bits_.capacity() * sizeof(uint64_t) + rank_before_.capacity() * sizeof(uint32_t);
  for (const Level& level : levels_) bytes += level.groups.capacity() * sizeof(Group);
  return bytes;
}

void HeightfieldTree::TriangleCorners(uint32_t triangle, const Eigen::Vector3f* corners[3]) const {
  uint32_t cell = triangle / 2;
  if (masked_) {
    // The cell of rank triangle / 2: its word by binary search, then its bit.
    const uint32_t rank = triangle / 2;
    const size_t w = size_t(std::upper_bound(rank_before_.begin(), rank_before_.end(), rank) - rank_before_.begin()) - 1;
    uint64_t bits = cell_bits_[w];
    for (uint32_t skip = rank - rank_before_[w]; skip > 0; --skip) bits &= bits - 1;
    cell = uint32_t(w * 64 + size_t(__builtin_ctzll(bits)));
  }
  CellCorners(cell, int(triangle % 2), corners);
}

void HeightfieldTree::CellCorners(uint32_t cell, int half, const Eigen::Vector3f* corners[3]) const {
  const int c = int(cell % uint32_t(width_ - 1)), r = int(cell / uint32_t(width_ - 1));
  const Eigen::Vector3i triangle = scene::GridCellTriangles(width_, c, r, column_cross_row_up_)[size_t(half)];
  for (int k = 0; k < 3; ++k) corners[k] = posts_ + triangle[k];
}

}  // namespace gissar::render
