// Nearest neighbours by the gap between sphere surfaces: a k-d tree over agent centres,
// and the brute-force selection the one-shot solver uses for a short list.
#pragma once

#include <cstddef>
#include <vector>

#include <Eigen/Geometry>

#include "magna_orca_cpp/types.h"

namespace magna_orca
{
// A neighbour found by a query: its index and the gap between the two surfaces
// (centre distance minus both radii; negative when they overlap).
struct Neighbor
{
  std::size_t index;
  double gap;
};

// Nearer first; equal gaps in index order, so every search returns the same list.
inline bool nearerThan(const Neighbor& a, const Neighbor& b)
{
  return a.gap < b.gap || (a.gap == b.gap && a.index < b.index);
}

// The gap between the surfaces of two spheres.
double surfaceGap(const Vector3& centre_a, double radius_a, const Vector3& centre_b, double radius_b);

// Keeps the `capacity` nearest neighbours offered to it, in order.
class NearestList
{
public:
  void reset(std::size_t capacity, double range);
  void offer(const Neighbor& candidate);
  // The gap a candidate must beat to enter the list.
  double bound() const;
  const std::vector<Neighbor>& items() const { return items_; }

private:
  std::size_t capacity_ = 0;
  double range_ = 0.0;
  std::vector<Neighbor> items_;
};

// The nearest `max_neighbors` of `self` among `others` with a gap below `range`.
void selectNeighbors(const Agent& self, const std::vector<Agent>& others, std::size_t max_neighbors, double range,
                     NearestList& out);

class NeighborIndex
{
public:
  // Agents' radii must already be resolved; the index keeps a pointer to `agents`.
  void build(const std::vector<Agent>& agents);
  // The nearest `max_neighbors` agents to agents[self] (itself excluded) with a gap below `range`.
  void query(std::size_t self, std::size_t max_neighbors, double range, NearestList& out) const;

private:
  struct Node
  {
    Eigen::AlignedBox3d box;
    std::size_t begin;
    std::size_t end;
    std::size_t left;  // children, or kLeaf
    std::size_t right;
  };
  static constexpr std::size_t kLeaf = static_cast<std::size_t>(-1);
  static constexpr std::size_t kLeafSize = 8;

  std::size_t buildNode(std::size_t begin, std::size_t end);
  void search(std::size_t node, std::size_t self, NearestList& out) const;

  const std::vector<Agent>* agents_ = nullptr;
  std::vector<std::size_t> order_;
  std::vector<Node> nodes_;
  double max_radius_ = 0.0;
};

}  // namespace magna_orca
