// Bad input is named, field by field; good input passes.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "magna_orca_cpp/validation.h"

using magna_orca::Agent;
using magna_orca::checkAgent;
using magna_orca::checkParams;
using magna_orca::Params;

namespace
{
::testing::AssertionResult mentions(const std::string& error, const std::string& field)
{
  if (error.find(field) != std::string::npos)
    return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "'" << error << "' does not mention " << field;
}
}  // namespace

TEST(Validation, DefaultsPass)
{
  EXPECT_EQ(checkParams(Params(), 1000), "");
  Agent agent;
  EXPECT_EQ(checkAgent(agent, Params(), "agent"), "");
}

TEST(Validation, ParamsNameTheirField)
{
  Params p;
  p.time_horizon = 0.0;
  EXPECT_TRUE(mentions(checkParams(p, 1000), "params.time_horizon (timeHorizon) is 0"));
  p = Params();
  p.time_step = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(mentions(checkParams(p, 1000), "params.time_step"));
  p = Params();
  p.neighbor_dist = -1.0;
  EXPECT_TRUE(mentions(checkParams(p, 1000), "params.neighbor_dist"));
  p = Params();
  p.max_speed = INFINITY;
  EXPECT_TRUE(mentions(checkParams(p, 1000), "params.max_speed"));
  p = Params();
  p.max_neighbors = 5000;
  EXPECT_TRUE(mentions(checkParams(p, 1000), "above the cap of 1000 neighbours per agent (~max_neighbors)"));
  EXPECT_TRUE(mentions(checkParams(p, 1000, magna_orca::serverParamNames()), "~N_neighbors_aware is 5000"));
}

TEST(Validation, AgentsNameTheirField)
{
  const Params p;
  Agent agent;
  agent.position.y() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(mentions(checkAgent(agent, p, "neighbors[3]"), "neighbors[3].position.y is nan"));
  agent = Agent();
  agent.preferred_velocity.z() = -INFINITY;
  EXPECT_TRUE(mentions(checkAgent(agent, p, "agent"), "agent.preferred_velocity.z is -inf"));
  agent = Agent();
  agent.radius = -1.0;
  EXPECT_TRUE(mentions(checkAgent(agent, p, "agents[4]"), "agents[4].radius is -1"));
  agent = Agent();
  Params no_default;
  no_default.agent_radius = 0.0;
  EXPECT_TRUE(mentions(checkAgent(agent, no_default, "agent"), "give a positive radius in either"));
}
