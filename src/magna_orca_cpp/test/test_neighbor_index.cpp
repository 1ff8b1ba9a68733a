// The k-d tree finds exactly the neighbours a brute-force scan finds, in the same order.
#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "magna_orca_cpp/neighbor_index.h"

using magna_orca::Agent;
using magna_orca::NearestList;
using magna_orca::NeighborIndex;
using magna_orca::Vector3;

namespace
{
std::vector<Agent> randomAgents(std::mt19937& rng, std::size_t count, double spread)
{
  std::uniform_real_distribution<double> coordinate(-spread, spread);
  std::uniform_real_distribution<double> radius(0.1, 1.5);
  std::vector<Agent> agents(count);
  for (Agent& agent : agents)
  {
    agent.position = Vector3(coordinate(rng), coordinate(rng), coordinate(rng));
    agent.radius = radius(rng);
  }
  return agents;
}

// Brute force over everyone except `self`.
std::vector<magna_orca::Neighbor> scan(const std::vector<Agent>& agents, std::size_t self, std::size_t k, double range)
{
  NearestList list;
  list.reset(k, range);
  for (std::size_t j = 0; j < agents.size(); ++j)
    if (j != self)
      list.offer({ j, magna_orca::surfaceGap(agents[self].position, agents[self].radius, agents[j].position,
                                             agents[j].radius) });
  return list.items();
}

void expectSameLists(const std::vector<magna_orca::Neighbor>& tree, const std::vector<magna_orca::Neighbor>& brute)
{
  ASSERT_EQ(tree.size(), brute.size());
  for (std::size_t n = 0; n < tree.size(); ++n)
  {
    EXPECT_EQ(tree[n].index, brute[n].index);
    EXPECT_EQ(tree[n].gap, brute[n].gap);
  }
}
}  // namespace

TEST(NeighborIndex, MatchesBruteForceOnRandomSets)
{
  std::mt19937 rng(3);
  for (std::size_t count : { 1u, 2u, 9u, 50u, 333u, 2000u })
  {
    const std::vector<Agent> agents = randomAgents(rng, count, 20.0);
    NeighborIndex index;
    index.build(agents);
    NearestList found;
    for (std::size_t k : { 0u, 1u, 5u, 10u, 64u })
      for (double range : { 0.5, 3.0, 1e9 })
        for (std::size_t self = 0; self < count; self += 1 + count / 40)
        {
          index.query(self, k, range, found);
          expectSameLists(found.items(), scan(agents, self, k, range));
        }
  }
}

TEST(NeighborIndex, TiesAreBrokenByIndexAndDuplicatesAreKept)
{
  // Agents 3 m along each axis from the first one all have exactly the same gap; two
  // pairs share a position.
  const Vector3 places[] = { Vector3(3, 0, 0), Vector3(-3, 0, 0), Vector3(0, 3, 0), Vector3(0, -3, 0),
                             Vector3(0, 0, 3), Vector3(0, 0, -3) };
  std::vector<Agent> agents(9);
  for (std::size_t i = 1; i < agents.size(); ++i)
    agents[i].position = places[(agents.size() - i) % 6];  // indices do not follow the build order
  for (Agent& agent : agents)
    agent.radius = 0.5;
  NeighborIndex index;
  index.build(agents);
  NearestList found;
  index.query(0, 4, 10.0, found);
  expectSameLists(found.items(), scan(agents, 0, 4, 10.0));
  ASSERT_EQ(found.items().size(), 4u);
  for (std::size_t n = 0; n < 4; ++n)
  {
    EXPECT_EQ(found.items()[n].index, n + 1) << "equal gaps: the lowest indices win";
    EXPECT_EQ(found.items()[n].gap, 2.0);
  }
}

TEST(NeighborIndex, GapCountsBetweenSurfacesNotCentres)
{
  // A big obstacle whose centre is 10 m away but whose surface is 1 m away is within 2 m.
  std::vector<Agent> agents(2);
  agents[0].radius = 0.5;
  agents[1].position = Vector3(10.0, 0.0, 0.0);
  agents[1].radius = 8.5;
  NeighborIndex index;
  index.build(agents);
  NearestList found;
  index.query(0, 5, 2.0, found);
  ASSERT_EQ(found.items().size(), 1u);
  EXPECT_NEAR(found.items()[0].gap, 1.0, 1e-12);
}
