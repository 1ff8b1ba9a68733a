// Closed loop: agents swap places through a common point, each step taking the ORCA
// velocity, and no two ever come closer than the sum of their radii (checked along the
// straight motion between steps, not only at the steps).
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "magna_orca_cpp/orca3d.h"

using magna_orca::Params;
using magna_orca::Simulator;
using magna_orca::Vector3;

namespace
{
// Agents that touch slide along each other on the exact boundary of their half-spaces;
// rounding may put them this far (1 nanometre) inside each other.
constexpr double kRounding = 1e-9;

// Points spread evenly on a sphere (Fibonacci lattice), or on a circle for two or four,
// moved by up to 1 cm: a perfectly symmetric crowd can stall in ORCA's known symmetric
// deadlock, which any real position noise breaks.
std::vector<Vector3> startPositions(std::size_t count, double radius)
{
  std::mt19937 rng(static_cast<unsigned>(count));
  std::uniform_real_distribution<double> jitter(-0.01, 0.01);
  std::vector<Vector3> points;
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  for (std::size_t i = 0; i < count; ++i)
  {
    if (count <= 4)
    {
      const double angle = 2.0 * M_PI * static_cast<double>(i) / static_cast<double>(count);
      points.emplace_back(radius * std::cos(angle) + jitter(rng), radius * std::sin(angle) + jitter(rng), jitter(rng));
      continue;
    }
    const double z = 1.0 - 2.0 * (static_cast<double>(i) + 0.5) / static_cast<double>(count);
    const double ring = std::sqrt(1.0 - z * z);
    const double angle = golden * static_cast<double>(i);
    points.emplace_back(radius * ring * std::cos(angle) + jitter(rng), radius * ring * std::sin(angle) + jitter(rng),
                        radius * z + jitter(rng));
  }
  return points;
}

Vector3 towards(const Vector3& from, const Vector3& goal, double max_speed, double time_step)
{
  const Vector3 gap = goal - from;
  const double distance = gap.norm();
  if (distance < 1e-9)
    return Vector3::Zero();
  // Full speed, slowing so as not to overshoot the goal within one step.
  return gap / distance * std::min(max_speed, distance / time_step);
}

// Smallest distance between two agents moving in straight lines from a to a_next, b to b_next.
double closestDuringStep(const Vector3& a, const Vector3& a_next, const Vector3& b, const Vector3& b_next)
{
  const Vector3 start = b - a;
  const Vector3 change = (b_next - a_next) - start;
  const double change_sq = change.squaredNorm();
  const double t = change_sq > 0 ? std::clamp(-start.dot(change) / change_sq, 0.0, 1.0) : 0.0;
  return (start + t * change).norm();
}

struct Outcome
{
  double worst_clearance;  // smallest (distance - sum of radii) seen
  bool all_arrived;
  double time;
};

Outcome swapThroughCentre(std::size_t count, double circle_radius, bool with_obstacle)
{
  Params params;
  // Everyone sees everyone: ORCA's guarantee covers the neighbours an agent looks at.
  params.max_neighbors = count + 1;
  params.time_step = 0.05;
  params.neighbor_dist = 50.0;
  params.time_horizon = 3.0;
  params.agent_radius = 0.5;
  params.max_speed = 2.0;
  Simulator sim(params);
  const std::vector<Vector3> starts = startPositions(count, circle_radius);
  std::vector<Vector3> goals;
  for (const Vector3& start : starts)
  {
    sim.addAgent(start);
    goals.push_back(-start);
  }
  std::size_t obstacle = count;
  if (with_obstacle)
    obstacle = sim.addAgent(Vector3::Zero(), 1.0, 0.0, false);  // a still sphere in everyone's way

  Outcome outcome{ INFINITY, false, 0.0 };
  for (int step = 0; step < 4000 && !outcome.all_arrived; ++step)
  {
    for (std::size_t i = 0; i < count; ++i)
      sim.setAgentPrefVelocity(i, towards(sim.getAgentPosition(i), goals[i], params.max_speed, params.time_step));
    std::vector<Vector3> before;
    for (std::size_t i = 0; i < sim.getNumAgents(); ++i)
      before.push_back(sim.getAgentPosition(i));
    sim.doStep();
    for (std::size_t i = 0; i < sim.getNumAgents(); ++i)
      for (std::size_t j = i + 1; j < sim.getNumAgents(); ++j)
      {
        const double distance =
            closestDuringStep(before[i], sim.getAgentPosition(i), before[j], sim.getAgentPosition(j));
        outcome.worst_clearance =
            std::min(outcome.worst_clearance, distance - sim.getAgentRadius(i) - sim.getAgentRadius(j));
      }
    outcome.all_arrived = true;
    for (std::size_t i = 0; i < count; ++i)
      outcome.all_arrived = outcome.all_arrived && (sim.getAgentPosition(i) - goals[i]).norm() < 0.05;
    outcome.time = sim.getGlobalTime();
  }
  if (with_obstacle)
    EXPECT_EQ(sim.getAgentPosition(obstacle), Vector3::Zero()) << "a non-cooperative agent keeps its course";
  return outcome;
}
}  // namespace

class SwapThroughCentre : public ::testing::TestWithParam<std::size_t>
{
};

TEST_P(SwapThroughCentre, NoTwoAgentsEverOverlapAndAllArrive)
{
  const std::size_t count = GetParam();
  const Outcome outcome = swapThroughCentre(count, count <= 4 ? 5.0 : 8.0, false);
  EXPECT_GE(outcome.worst_clearance, -kRounding) << count << " agents";
  EXPECT_TRUE(outcome.all_arrived) << count << " agents still travelling after " << outcome.time << " s";
}

INSTANTIATE_TEST_SUITE_P(Agents, SwapThroughCentre, ::testing::Values(2u, 4u, 20u));

TEST(SwapThroughCentre, AStillObstacleInTheMiddleIsAvoidedByEveryone)
{
  const Outcome outcome = swapThroughCentre(20, 8.0, true);
  EXPECT_GE(outcome.worst_clearance, -kRounding);
  EXPECT_TRUE(outcome.all_arrived) << "still travelling after " << outcome.time << " s";
}

TEST(Simulator, BadIndexIsReportedNotUndefined)
{
  Simulator sim;
  sim.addAgent(Vector3::Zero());
  EXPECT_THROW(sim.getAgentPosition(3), std::out_of_range);
  EXPECT_THROW(sim.setAgentPrefVelocity(1, Vector3::Zero()), std::out_of_range);
}

TEST(Simulator, LoneAgentFliesItsPreferredVelocityCappedAtMaxSpeed)
{
  Params params;
  params.time_step = 0.5;
  Simulator sim(params);
  sim.addAgent(Vector3::Zero(), 0.5, 1.0);
  sim.setAgentPrefVelocity(0, Vector3(3.0, 4.0, 0.0));
  sim.doStep();
  EXPECT_NEAR((sim.getAgentVelocity(0) - Vector3(0.6, 0.8, 0.0)).norm(), 0.0, 1e-12);
  EXPECT_NEAR((sim.getAgentPosition(0) - Vector3(0.3, 0.4, 0.0)).norm(), 0.0, 1e-12);
  EXPECT_DOUBLE_EQ(sim.getGlobalTime(), 0.5);
  EXPECT_TRUE(sim.wasAgentFeasible(0));
}
