#include "magna_orca_cpp/neighbor_index.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace magna_orca
{
double surfaceGap(const Vector3& centre_a, double radius_a, const Vector3& centre_b, double radius_b)
{
  return (centre_b - centre_a).norm() - radius_a - radius_b;
}

void NearestList::reset(std::size_t capacity, double range)
{
  capacity_ = capacity;
  range_ = range;
  items_.clear();
}

double NearestList::bound() const
{
  if (capacity_ > 0 && items_.size() == capacity_)
    return items_.back().gap;
  return range_;
}

void NearestList::offer(const Neighbor& candidate)
{
  if (capacity_ == 0 || !(candidate.gap < range_))
    return;
  if (items_.size() == capacity_)
  {
    if (!nearerThan(candidate, items_.back()))
      return;
    items_.pop_back();
  }
  // Lists are short (N_neighbors_aware): insertion keeps them sorted cheaply.
  const auto where = std::upper_bound(items_.begin(), items_.end(), candidate, nearerThan);
  items_.insert(where, candidate);
}

void selectNeighbors(const Agent& self, const std::vector<Agent>& others, std::size_t max_neighbors, double range,
                     NearestList& out)
{
  out.reset(max_neighbors, range);
  for (std::size_t j = 0; j < others.size(); ++j)
    out.offer(Neighbor{ j, surfaceGap(self.position, self.radius, others[j].position, others[j].radius) });
}

void NeighborIndex::build(const std::vector<Agent>& agents)
{
  agents_ = &agents;
  order_.resize(agents.size());
  for (std::size_t i = 0; i < agents.size(); ++i)
    order_[i] = i;
  max_radius_ = 0.0;
  for (const Agent& agent : agents)
    max_radius_ = std::max(max_radius_, agent.radius);
  nodes_.clear();
  nodes_.reserve(2 * agents.size() / kLeafSize + 2);
  if (!agents.empty())
    buildNode(0, agents.size());
}

std::size_t NeighborIndex::buildNode(std::size_t begin, std::size_t end)
{
  const std::vector<Agent>& agents = *agents_;
  Eigen::AlignedBox3d box;
  for (std::size_t k = begin; k < end; ++k)
    box.extend(agents[order_[k]].position);
  const std::size_t id = nodes_.size();
  nodes_.push_back(Node{ box, begin, end, kLeaf, kLeaf });
  if (end - begin <= kLeafSize)
    return id;

  // Split at the median of the box's longest side.
  Eigen::Index axis;
  box.sizes().maxCoeff(&axis);
  const std::size_t middle = begin + (end - begin) / 2;
  std::nth_element(order_.begin() + begin, order_.begin() + middle, order_.begin() + end,
                   [&](std::size_t a, std::size_t b) { return agents[a].position[axis] < agents[b].position[axis]; });
  const std::size_t left = buildNode(begin, middle);
  const std::size_t right = buildNode(middle, end);
  nodes_[id].left = left;
  nodes_[id].right = right;
  return id;
}

void NeighborIndex::query(std::size_t self, std::size_t max_neighbors, double range, NearestList& out) const
{
  out.reset(max_neighbors, range);
  if (!nodes_.empty() && max_neighbors > 0)
    search(0, self, out);
}

void NeighborIndex::search(std::size_t node_id, std::size_t self, NearestList& out) const
{
  const std::vector<Agent>& agents = *agents_;
  const Agent& me = agents[self];
  const Node& node = nodes_[node_id];
  if (node.left == kLeaf)
  {
    for (std::size_t k = node.begin; k < node.end; ++k)
    {
      const std::size_t j = order_[k];
      if (j != self)
        out.offer(Neighbor{ j, surfaceGap(me.position, me.radius, agents[j].position, agents[j].radius) });
    }
    return;
  }
  // Visit the nearer child first; skip a child whose box cannot hold a gap below the bound.
  const double reach = me.radius + max_radius_;
  const Node& left = nodes_[node.left];
  const Node& right = nodes_[node.right];
  const double left_gap = std::sqrt(left.box.squaredExteriorDistance(me.position)) - reach;
  const double right_gap = std::sqrt(right.box.squaredExteriorDistance(me.position)) - reach;
  const bool left_first = left_gap <= right_gap;
  const std::size_t first = left_first ? node.left : node.right;
  const std::size_t second = left_first ? node.right : node.left;
  const double first_gap = left_first ? left_gap : right_gap;
  const double second_gap = left_first ? right_gap : left_gap;
  // <= keeps boxes that may hold a tie with the current worst (ties are broken by index).
  if (first_gap <= out.bound())
    search(first, self, out);
  if (second_gap <= out.bound())
    search(second, self, out);
}

}  // namespace magna_orca
