// ORCA-3D solving: one agent against a given neighbour list, or every agent of a set
// against the others, and a small simulator in the spirit of RVO2-3D.
#pragma once

#include <cstddef>
#include <vector>

#include "magna_orca_cpp/linear_program.h"
#include "magna_orca_cpp/neighbor_index.h"
#include "magna_orca_cpp/types.h"

namespace magna_orca
{
// A copy of `agent` with radius and max speed taken from `params` where it gives 0.
Agent withDefaults(const Agent& agent, const Params& params);

// Reusable buffers, so repeated solves do not allocate.
struct Workspace
{
  std::vector<Agent> resolved;  // the candidates with their defaults applied
  NearestList neighbors;
  std::vector<Plane> planes;
  std::vector<Plane> scratch;
};

// The half-spaces `neighbors` (a selection of `others`) impose on `self`, nearest first.
void buildHalfSpaces(const Agent& self, const std::vector<Agent>& others, const std::vector<Neighbor>& neighbors,
                     const Params& params, std::vector<Plane>& planes);

// New velocity of `self` given the agents it may see: the nearest params.max_neighbors whose
// surfaces are closer than params.neighbor_dist are avoided. A non-cooperative `self` keeps
// its preferred velocity. Radii and speeds of 0 take the defaults in `params`.
Solution newVelocity(const Agent& self, const std::vector<Agent>& others, const Params& params);
Solution newVelocity(const Agent& self, const std::vector<Agent>& others, const Params& params, Workspace& work);

// New velocities of all `agents`, each avoiding its nearest neighbours among the others.
std::vector<Solution> newVelocities(const std::vector<Agent>& agents, const Params& params);

// Add agents, set preferred velocities, step, read velocities and positions.
class Simulator
{
public:
  explicit Simulator(const Params& params = Params());

  // Returns the agent's index. A radius or max speed of 0 takes the default from the params.
  std::size_t addAgent(const Vector3& position, double radius = 0.0, double max_speed = 0.0,
                       bool cooperative = true, const Vector3& velocity = Vector3::Zero());
  void setAgentPrefVelocity(std::size_t agent, const Vector3& preferred_velocity);
  void setAgentPosition(std::size_t agent, const Vector3& position);
  void setAgentVelocity(std::size_t agent, const Vector3& velocity);

  // Every cooperative agent takes its ORCA velocity, every other its preferred one; then
  // all move for one time step.
  void doStep();

  std::size_t getNumAgents() const { return agents_.size(); }
  const Vector3& getAgentPosition(std::size_t agent) const;
  const Vector3& getAgentVelocity(std::size_t agent) const;
  const Vector3& getAgentPrefVelocity(std::size_t agent) const;
  double getAgentRadius(std::size_t agent) const;
  // Whether the agent's last program met every half-space.
  bool wasAgentFeasible(std::size_t agent) const;
  double getGlobalTime() const { return time_; }
  const Params& params() const { return params_; }

private:
  const Agent& at(std::size_t agent) const;

  Params params_;
  std::vector<Agent> agents_;
  std::vector<Solution> last_;
  double time_ = 0.0;
};

}  // namespace magna_orca
