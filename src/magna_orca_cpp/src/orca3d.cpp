#include "magna_orca_cpp/orca3d.h"

#include <stdexcept>
#include <string>

#include "magna_orca_cpp/half_space.h"

namespace magna_orca
{
Agent withDefaults(const Agent& agent, const Params& params)
{
  Agent resolved = agent;
  if (resolved.radius == 0.0)
    resolved.radius = params.agent_radius;
  if (resolved.max_speed == 0.0)
    resolved.max_speed = params.max_speed;
  return resolved;
}

void buildHalfSpaces(const Agent& self, const std::vector<Agent>& others, const std::vector<Neighbor>& neighbors,
                     const Params& params, std::vector<Plane>& planes)
{
  planes.clear();
  for (const Neighbor& neighbor : neighbors)
  {
    const Agent& other = others[neighbor.index];
    const double share = other.cooperative ? kSharedResponsibility : kFullResponsibility;
    planes.push_back(orcaHalfSpace(self, other, params.time_horizon, params.time_step, share));
  }
}

namespace
{
Solution solveAgainst(const Agent& self, const std::vector<Agent>& others, const Params& params, Workspace& work)
{
  buildHalfSpaces(self, others, work.neighbors.items(), params, work.planes);
  return solveVelocity(work.planes, self.max_speed, self.preferred_velocity, work.scratch);
}
}  // namespace

Solution newVelocity(const Agent& self, const std::vector<Agent>& others, const Params& params, Workspace& work)
{
  const Agent me = withDefaults(self, params);
  if (!me.cooperative)
    return Solution{ me.preferred_velocity, true };
  work.resolved.clear();
  for (const Agent& other : others)
    work.resolved.push_back(withDefaults(other, params));
  selectNeighbors(me, work.resolved, params.max_neighbors, params.neighbor_dist, work.neighbors);
  return solveAgainst(me, work.resolved, params, work);
}

Solution newVelocity(const Agent& self, const std::vector<Agent>& others, const Params& params)
{
  Workspace work;
  return newVelocity(self, others, params, work);
}

std::vector<Solution> newVelocities(const std::vector<Agent>& agents, const Params& params)
{
  std::vector<Agent> resolved;
  resolved.reserve(agents.size());
  for (const Agent& agent : agents)
    resolved.push_back(withDefaults(agent, params));
  NeighborIndex index;
  index.build(resolved);
  Workspace work;
  std::vector<Solution> solutions(resolved.size());
  for (std::size_t i = 0; i < resolved.size(); ++i)
  {
    const Agent& me = resolved[i];
    if (!me.cooperative)
    {
      solutions[i] = Solution{ me.preferred_velocity, true };
      continue;
    }
    index.query(i, params.max_neighbors, params.neighbor_dist, work.neighbors);
    solutions[i] = solveAgainst(me, resolved, params, work);
  }
  return solutions;
}

Simulator::Simulator(const Params& params) : params_(params)
{
}

std::size_t Simulator::addAgent(const Vector3& position, double radius, double max_speed, bool cooperative,
                                const Vector3& velocity)
{
  Agent agent;
  agent.position = position;
  agent.velocity = velocity;
  agent.radius = radius;
  agent.max_speed = max_speed;
  agent.cooperative = cooperative;
  agents_.push_back(withDefaults(agent, params_));
  last_.push_back(Solution{ velocity, true });
  return agents_.size() - 1;
}

const Agent& Simulator::at(std::size_t agent) const
{
  if (agent >= agents_.size())
    throw std::out_of_range("ORCA-3D simulator: no agent " + std::to_string(agent) + " (it has " +
                            std::to_string(agents_.size()) + ")");
  return agents_[agent];
}

void Simulator::setAgentPrefVelocity(std::size_t agent, const Vector3& preferred_velocity)
{
  at(agent);
  agents_[agent].preferred_velocity = preferred_velocity;
}

void Simulator::setAgentPosition(std::size_t agent, const Vector3& position)
{
  at(agent);
  agents_[agent].position = position;
}

void Simulator::setAgentVelocity(std::size_t agent, const Vector3& velocity)
{
  at(agent);
  agents_[agent].velocity = velocity;
}

void Simulator::doStep()
{
  last_ = newVelocities(agents_, params_);
  for (std::size_t i = 0; i < agents_.size(); ++i)
  {
    agents_[i].velocity = last_[i].velocity;
    agents_[i].position += params_.time_step * agents_[i].velocity;
  }
  time_ += params_.time_step;
}

const Vector3& Simulator::getAgentPosition(std::size_t agent) const
{
  return at(agent).position;
}

const Vector3& Simulator::getAgentVelocity(std::size_t agent) const
{
  return at(agent).velocity;
}

const Vector3& Simulator::getAgentPrefVelocity(std::size_t agent) const
{
  return at(agent).preferred_velocity;
}

double Simulator::getAgentRadius(std::size_t agent) const
{
  return at(agent).radius;
}

bool Simulator::wasAgentFeasible(std::size_t agent) const
{
  at(agent);
  return last_[agent].feasible;
}

}  // namespace magna_orca
