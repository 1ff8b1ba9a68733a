// /compute_velocity_many against /compute_velocity, through the handlers the node serves
// (no master needed): every problem's answer equals its one-agent answer bit for bit, and a
// refusal names the problem and the field.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "magna_orca_cpp/service_conversion.h"

namespace service = magna_orca::service;
using magna_msgs::OrcaAgent;
using magna_msgs::OrcaComputeVelocity;
using magna_msgs::OrcaComputeVelocityMany;
using magna_msgs::OrcaParams;
using magna_msgs::OrcaProblem;

namespace
{
geometry_msgs::Vector3 vec(double x, double y, double z)
{
  geometry_msgs::Vector3 v;
  v.x = x;
  v.y = y;
  v.z = z;
  return v;
}

OrcaAgent agent(std::uint32_t id, const geometry_msgs::Vector3& position, const geometry_msgs::Vector3& velocity,
                const geometry_msgs::Vector3& preferred, double radius = 0.0, double max_speed = 0.0,
                bool cooperative = true)
{
  OrcaAgent a;
  a.id = id;
  a.position.x = position.x;
  a.position.y = position.y;
  a.position.z = position.z;
  a.velocity = velocity;
  a.preferred_velocity = preferred;
  a.radius = radius;
  a.max_speed = max_speed;
  a.non_cooperative = !cooperative;
  return a;
}

OrcaProblem problem(const OrcaAgent& self, const std::vector<OrcaAgent>& neighbors, const OrcaParams& params)
{
  OrcaProblem p;
  p.agent = self;
  p.neighbors = neighbors;
  p.params = params;
  return p;
}

OrcaParams requestParams(std::uint32_t neighbors, double time_horizon)
{
  OrcaParams p;
  p.n_neighbors_aware = neighbors;
  p.time_step = 0.1;
  p.neighbor_dist = 8.0;
  p.time_horizon = time_horizon;
  p.agent_radius = 0.5;
  p.max_speed = 2.0;
  return p;
}

// The fixed cases of orca3d_server_rostest.py (head-on, a crowd with a still obstacle and an
// agent out of range, more neighbours than N_neighbors_aware, overlap, boxed in and
// infeasible, a non-cooperative agent), each with the server's parameters (all-zero block).
std::vector<OrcaProblem> fixedProblems()
{
  const OrcaParams server;  // all zero
  const geometry_msgs::Vector3 still = vec(0, 0, 0);
  std::vector<OrcaProblem> problems;
  problems.push_back(problem(agent(1, vec(0, 0, 5), vec(1, 0, 0), vec(1, 0, 0)),
                             { agent(2, vec(4, 0, 5), vec(-1, 0, 0), vec(-1, 0, 0)) }, server));
  problems.push_back(problem(agent(3, vec(0, 0, 2), vec(1.5, 0, 0), vec(2, 0, 0), 0.4),
                             { agent(10, vec(3, 0.5, 2), vec(-1, 0, 0), vec(-1, 0, 0)),
                               agent(11, vec(1, 2, 2.3), vec(0, -1, 0), vec(0, -1, 0), 0.3, 1.0),
                               agent(12, vec(2, -1, 2), still, still, 0.8, 0.0, false),
                               agent(13, vec(-2, 0.5, 1.5), vec(1.2, 0, 0.1), vec(1.5, 0, 0), 0.5),
                               agent(14, vec(1.5, 0.2, 3.5), vec(0, 0, -1), vec(0, 0, -1), 0.45, 3.0),
                               agent(15, vec(30, 0, 2), vec(-2, 0, 0), vec(-2, 0, 0)) },
                             server));
  problems.push_back(problem(agent(5, vec(0, 0, 0), vec(0.2, 0, 0), vec(1, 0, 0), 0.5),
                             { agent(30, vec(0.8, 0.1, 0), vec(-0.2, 0, 0), vec(-1, 0, 0), 0.5) }, server));
  problems.push_back(problem(agent(6, still, still, vec(1, 0, 0), 0.5, 0.5),
                             { agent(40, vec(0.9, 0, 0), still, still, 0.5, 0.0, false),
                               agent(41, vec(-0.9, 0, 0), still, still, 0.5, 0.0, false) },
                             server));
  problems.push_back(problem(agent(7, still, vec(1, 0, 0), vec(1, 0, 0), 0.0, 0.0, false),
                             { agent(50, vec(2, 0, 0), vec(-1, 0, 0), vec(-1, 0, 0)) }, server));
  return problems;
}

// Seeded random problems in the manner of magna_orca_cpp/scenarios.py: mixed radii and
// speeds, a quarter non-cooperative (half of those still), dense enough to overlap and to
// make programs infeasible; each problem its own parameters, every fifth the server's.
std::vector<OrcaProblem> randomProblems(unsigned seed, std::size_t count, std::size_t min_neighbors,
                                        std::size_t max_neighbors)
{
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::vector<OrcaProblem> problems;
  std::uint32_t next_id = 1;
  for (std::size_t s = 0; s < count; ++s)
  {
    const std::size_t n = std::uniform_int_distribution<std::size_t>(min_neighbors, max_neighbors)(rng);
    const double spread = 2.0 + 0.5 * std::cbrt(static_cast<double>(n));
    auto draw = [&](double scale) { return vec(scale * normal(rng), scale * normal(rng), scale * normal(rng)); };
    auto around = [&]() {
      return vec(spread * (2 * unit(rng) - 1), spread * (2 * unit(rng) - 1), spread * (2 * unit(rng) - 1));
    };
    const OrcaAgent self = agent(next_id++, vec(0, 0, 0), draw(1.0), draw(1.3), 0.2 + 0.8 * unit(rng),
                                 1.0 + 2.0 * unit(rng));
    std::vector<OrcaAgent> neighbors;
    for (std::size_t k = 0; k < n; ++k)
    {
      const bool cooperative = unit(rng) > 0.25;
      const bool still = !cooperative && unit(rng) < 0.5;
      const geometry_msgs::Vector3 velocity = still ? vec(0, 0, 0) : draw(1.0);
      const geometry_msgs::Vector3 preferred = still ? vec(0, 0, 0) : draw(1.3);
      neighbors.push_back(agent(next_id++, around(), velocity, preferred, unit(rng) < 0.1 ? 0.0 : 0.2 + 0.8 * unit(rng),
                                unit(rng) < 0.1 ? 0.0 : 1.0 + 2.0 * unit(rng), cooperative));
    }
    const OrcaParams params =
        s % 5 == 0 ? OrcaParams() : requestParams(static_cast<std::uint32_t>(1 + s % 12), 0.5 + 5.5 * unit(rng));
    problems.push_back(problem(self, neighbors, params));
  }
  return problems;
}

std::uint64_t bits(double value)
{
  std::uint64_t out;
  std::memcpy(&out, &value, sizeof out);
  return out;
}

OrcaComputeVelocity::Response solveOne(const OrcaProblem& p, const service::Settings& settings)
{
  OrcaComputeVelocity::Request req;
  req.agent = p.agent;
  req.neighbors = p.neighbors;
  req.params = p.params;
  OrcaComputeVelocity::Response res;
  service::computeVelocity(req, res, settings);
  return res;
}

OrcaComputeVelocityMany::Response solveMany(const std::vector<OrcaProblem>& problems,
                                            const service::Settings& settings)
{
  OrcaComputeVelocityMany::Request req;
  req.problems = problems;
  OrcaComputeVelocityMany::Response res;
  service::computeVelocityMany(req, res, settings);
  return res;
}

// Many-call == one call per problem, bit for bit, in order.
void expectManyEqualsOnes(const std::vector<OrcaProblem>& problems, const service::Settings& settings)
{
  const OrcaComputeVelocityMany::Response many = solveMany(problems, settings);
  ASSERT_TRUE(many.success) << many.message;
  ASSERT_EQ(many.velocities.size(), problems.size());
  ASSERT_EQ(many.feasible.size(), problems.size());
  for (std::size_t i = 0; i < problems.size(); ++i)
  {
    const OrcaComputeVelocity::Response one = solveOne(problems[i], settings);
    ASSERT_TRUE(one.success) << "problem " << i << ": " << one.message;
    EXPECT_EQ(bits(many.velocities[i].x), bits(one.velocity.x)) << "problem " << i;
    EXPECT_EQ(bits(many.velocities[i].y), bits(one.velocity.y)) << "problem " << i;
    EXPECT_EQ(bits(many.velocities[i].z), bits(one.velocity.z)) << "problem " << i;
    EXPECT_EQ(static_cast<bool>(many.feasible[i]), static_cast<bool>(one.feasible)) << "problem " << i;
  }
}

service::Settings rostestSettings()
{
  // The parameters orca3d_server.test starts the node with: the all-zero blocks take these.
  service::Settings settings;
  settings.params.max_neighbors = 8;
  settings.params.time_step = 0.05;
  settings.params.neighbor_dist = 7.0;
  settings.params.time_horizon = 4.0;
  settings.params.agent_radius = 0.6;
  settings.params.max_speed = 2.5;
  return settings;
}

::testing::AssertionResult startsWith(const std::string& text, const std::string& prefix)
{
  if (text.compare(0, prefix.size(), prefix) == 0)
    return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "'" << text << "' does not start with '" << prefix << "'";
}
}  // namespace

TEST(ServiceMany, FixedScenariosEqualOneCallEach)
{
  expectManyEqualsOnes(fixedProblems(), rostestSettings());
}

TEST(ServiceMany, RandomScenariosEqualOneCallEach)
{
  const std::vector<OrcaProblem> problems = randomProblems(8, 400, 0, 30);
  std::size_t infeasible = 0;
  for (const OrcaProblem& p : problems)
    infeasible += solveOne(p, rostestSettings()).feasible ? 0 : 1;
  EXPECT_GT(infeasible, 0u) << "the scenarios should reach the least-violation branch too";
  expectManyEqualsOnes(problems, rostestSettings());
}

TEST(ServiceMany, SixtyFourFiftyUavNeighbourhoodsPassTheDefaultCaps)
{
  std::vector<OrcaProblem> problems = randomProblems(3, 64, 0, 0);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> place(-20.0, 20.0);
  for (std::size_t s = 0; s < problems.size(); ++s)
    for (std::uint32_t k = 0; k < 50; ++k)  // 49 other UAVs and an obstacle or two: 50 agents
      problems[s].neighbors.push_back(agent(1000 + k, vec(place(rng), place(rng), place(rng)), vec(0, 0, 0),
                                            vec(0, 0, 0), 0.3, 2.0, k < 49));
  expectManyEqualsOnes(problems, service::Settings());
}

TEST(ServiceMany, EmptyCallSucceedsWithNoAnswers)
{
  const OrcaComputeVelocityMany::Response res = solveMany({}, service::Settings());
  EXPECT_TRUE(res.success) << res.message;
  EXPECT_TRUE(res.velocities.empty());
}

TEST(ServiceMany, RefusalsNameTheProblemAndTheField)
{
  const service::Settings settings = rostestSettings();
  const std::vector<OrcaProblem> good = randomProblems(21, 6, 2, 4);

  auto refusal = [&settings](const std::vector<OrcaProblem>& problems) {
    const OrcaComputeVelocityMany::Response res = solveMany(problems, settings);
    EXPECT_FALSE(res.success);
    EXPECT_TRUE(res.velocities.empty() && res.feasible.empty()) << "a refused call gives no partial answers";
    return res.message;
  };

  std::vector<OrcaProblem> bad = good;
  bad[3].agent.radius = -1.0;
  EXPECT_TRUE(startsWith(refusal(bad), "problems[3].agent.radius is -1: "));

  bad = good;
  bad[4].neighbors.at(0).velocity.y = std::numeric_limits<double>::infinity();
  EXPECT_TRUE(startsWith(refusal(bad), "problems[4].neighbors[0].velocity.y is inf: give a finite number"));

  bad = good;
  bad[2].params = requestParams(3, 0.0);
  EXPECT_TRUE(startsWith(refusal(bad), "problems[2].params.time_horizon (timeHorizon) is 0: "));

  bad = good;
  bad[5].neighbors.at(1).id = bad[5].agent.id;
  EXPECT_TRUE(startsWith(refusal(bad), "problems[5].neighbors[1].id " + std::to_string(bad[5].agent.id) +
                                           " repeats problems[5].agent.id"));

  service::Settings capped = settings;
  capped.max_neighbors = 3;
  bad = good;
  bad[1].neighbors.resize(4, bad[1].neighbors.at(0));
  const OrcaComputeVelocityMany::Response crowded = solveMany(bad, capped);
  EXPECT_TRUE(startsWith(crowded.message, "problems[1].neighbors has 4 entries: this server takes at most 3 per "
                                          "problem (~max_neighbors)"));

  capped = settings;
  capped.max_agents = 5;
  const OrcaComputeVelocityMany::Response many = solveMany(good, capped);
  EXPECT_FALSE(many.success);
  EXPECT_TRUE(startsWith(many.message, "problems has 6 entries: this server takes at most 5 per call (~max_agents)"));
}

TEST(ServiceMany, TheOneAgentRefusalsKeepTheirNames)
{
  std::vector<OrcaProblem> problems = randomProblems(21, 1, 3, 4);
  problems[0].neighbors.at(2).radius = -1.0;
  const OrcaComputeVelocity::Response res = solveOne(problems[0], rostestSettings());
  EXPECT_FALSE(res.success);
  EXPECT_TRUE(startsWith(res.message, "neighbors[2].radius is -1: "));
}
