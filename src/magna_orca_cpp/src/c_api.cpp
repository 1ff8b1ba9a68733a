#include "magna_orca_cpp/c_api.h"

#include <chrono>
#include <cmath>
#include <cstring>
#include <exception>
#include <limits>
#include <string>
#include <vector>

#include "magna_orca_cpp/half_space.h"
#include "magna_orca_cpp/orca3d.h"
#include "magna_orca_cpp/validation.h"

using magna_orca::Agent;
using magna_orca::Params;
using magna_orca::Plane;
using magna_orca::Solution;
using magna_orca::Vector3;

namespace
{
constexpr int kOk = 0;
constexpr int kInternal = 1;
constexpr int kBadInput = 2;
// The C interface sets no cap of its own on N_neighbors_aware; the service does.
constexpr std::size_t kNoLimit = std::numeric_limits<std::size_t>::max();

struct BadInput
{
  std::string message;
};

void writeError(const std::string& message, char* error, std::size_t error_size)
{
  if (error == nullptr || error_size == 0)
    return;
  std::strncpy(error, message.c_str(), error_size - 1);
  error[error_size - 1] = '\0';
}

Params readParams(const double* row)
{
  if (!(row[0] >= 0.0) || row[0] != std::floor(row[0]) || row[0] > 1e9)
    throw BadInput{ "params.n_neighbors_aware is " + std::to_string(row[0]) + ": give a whole number >= 0" };
  Params params;
  params.max_neighbors = static_cast<std::size_t>(row[0]);
  params.time_step = row[1];
  params.neighbor_dist = row[2];
  params.time_horizon = row[3];
  params.agent_radius = row[4];
  params.max_speed = row[5];
  const std::string error = magna_orca::checkParams(params, kNoLimit);
  if (!error.empty())
    throw BadInput{ error };
  return params;
}

Agent readAgent(const double* row, const Params& params, const std::string& where)
{
  Agent agent;
  agent.position = Vector3(row[0], row[1], row[2]);
  agent.velocity = Vector3(row[3], row[4], row[5]);
  agent.preferred_velocity = Vector3(row[6], row[7], row[8]);
  agent.radius = row[9];
  agent.max_speed = row[10];
  agent.cooperative = row[11] != 0.0;
  const std::string error = magna_orca::checkAgent(agent, params, where);
  if (!error.empty())
    throw BadInput{ error };
  return agent;
}

std::vector<Agent> readAgents(const double* rows, std::size_t count, const Params& params, const char* name)
{
  std::vector<Agent> agents;
  agents.reserve(count);
  for (std::size_t i = 0; i < count; ++i)
    agents.push_back(readAgent(rows + i * MAGNA_ORCA_AGENT_FIELDS, params,
                               std::string(name) + "[" + std::to_string(i) + "]"));
  return agents;
}

void writeSeconds(std::chrono::steady_clock::time_point start, double* seconds)
{
  if (seconds != nullptr)
    *seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void writeSolution(const Solution& solution, double* velocity, int* feasible)
{
  velocity[0] = solution.velocity.x();
  velocity[1] = solution.velocity.y();
  velocity[2] = solution.velocity.z();
  *feasible = solution.feasible ? 1 : 0;
}

// Runs `body`, turning bad input and unexpected failures into return codes and messages.
template <typename Body>
int guarded(char* error, std::size_t error_size, Body body)
{
  try
  {
    body();
    return kOk;
  }
  catch (const BadInput& bad)
  {
    writeError(bad.message, error, error_size);
    return kBadInput;
  }
  catch (const std::exception& failure)
  {
    writeError(std::string("ORCA-3D failed: ") + failure.what(), error, error_size);
    return kInternal;
  }
}
}  // namespace

extern "C" {

int magna_orca_new_velocity(const double* agent, const double* others, size_t n_others, const double* params,
                            double* velocity, int* feasible, char* error, size_t error_size)
{
  return guarded(error, error_size, [&] {
    const Params p = readParams(params);
    const Agent self = readAgent(agent, p, "agent");
    const std::vector<Agent> neighbors = readAgents(others, n_others, p, "neighbors");
    writeSolution(magna_orca::newVelocity(self, neighbors, p), velocity, feasible);
  });
}

int magna_orca_new_velocity_many(const double* agents, size_t n_problems, const double* others, const size_t* offsets,
                                 const double* params, double* velocities, int* feasible, double* solve_seconds,
                                 char* error, size_t error_size)
{
  return guarded(error, error_size, [&] {
    const Params p = readParams(params);
    // Read and check everything first, so the timed loop below only solves.
    std::vector<Agent> selves = readAgents(agents, n_problems, p, "agents");
    std::vector<std::vector<Agent>> neighbor_lists(n_problems);
    for (std::size_t s = 0; s < n_problems; ++s)
    {
      if (offsets[s + 1] < offsets[s])
        throw BadInput{ "offsets[" + std::to_string(s + 1) + "] is below offsets[" + std::to_string(s) + "]" };
      neighbor_lists[s] = readAgents(others + offsets[s] * MAGNA_ORCA_AGENT_FIELDS, offsets[s + 1] - offsets[s], p,
                                     "others");
    }
    std::vector<Solution> solutions(n_problems);
    magna_orca::Workspace work;
    const auto start = std::chrono::steady_clock::now();
    for (std::size_t s = 0; s < n_problems; ++s)
      solutions[s] = magna_orca::newVelocity(selves[s], neighbor_lists[s], p, work);
    writeSeconds(start, solve_seconds);
    for (std::size_t s = 0; s < n_problems; ++s)
      writeSolution(solutions[s], velocities + 3 * s, feasible + s);
  });
}

int magna_orca_new_velocities(const double* agents, size_t n_agents, const double* params, double* velocities,
                              int* feasible, double* solve_seconds, char* error, size_t error_size)
{
  return guarded(error, error_size, [&] {
    const Params p = readParams(params);
    const std::vector<Agent> read = readAgents(agents, n_agents, p, "agents");
    const auto start = std::chrono::steady_clock::now();
    const std::vector<Solution> solutions = magna_orca::newVelocities(read, p);
    writeSeconds(start, solve_seconds);
    for (std::size_t i = 0; i < solutions.size(); ++i)
      writeSolution(solutions[i], velocities + 3 * i, feasible + i);
  });
}

int magna_orca_half_spaces(const double* agent, const double* others, size_t n_others, const double* params,
                           double* planes, size_t* n_planes, char* error, size_t error_size)
{
  return guarded(error, error_size, [&] {
    const Params p = readParams(params);
    const Agent self = magna_orca::withDefaults(readAgent(agent, p, "agent"), p);
    std::vector<Agent> neighbors = readAgents(others, n_others, p, "neighbors");
    for (Agent& neighbor : neighbors)
      neighbor = magna_orca::withDefaults(neighbor, p);
    magna_orca::NearestList nearest;
    magna_orca::selectNeighbors(self, neighbors, p.max_neighbors, p.neighbor_dist, nearest);
    std::vector<Plane> built;
    magna_orca::buildHalfSpaces(self, neighbors, nearest.items(), p, built);
    for (std::size_t k = 0; k < built.size(); ++k)
    {
      double* row = planes + k * MAGNA_ORCA_PLANE_FIELDS;
      for (int axis = 0; axis < 3; ++axis)
      {
        row[axis] = built[k].point[axis];
        row[3 + axis] = built[k].normal[axis];
      }
    }
    *n_planes = built.size();
  });
}

int magna_orca_solve_velocity(const double* planes, size_t n_planes, double max_speed, const double* preferred,
                              double* velocity, int* feasible, char* error, size_t error_size)
{
  return guarded(error, error_size, [&] {
    if (!std::isfinite(max_speed) || max_speed <= 0.0)
      throw BadInput{ "max_speed is " + std::to_string(max_speed) + ": give a positive speed" };
    std::vector<Plane> rows(n_planes);
    for (std::size_t k = 0; k < n_planes; ++k)
    {
      const double* row = planes + k * MAGNA_ORCA_PLANE_FIELDS;
      rows[k].point = Vector3(row[0], row[1], row[2]);
      rows[k].normal = Vector3(row[3], row[4], row[5]);
      if (!rows[k].point.allFinite() || !rows[k].normal.allFinite() || std::abs(rows[k].normal.norm() - 1.0) > 1e-9)
        throw BadInput{ "planes[" + std::to_string(k) + "] needs a finite point and a unit normal" };
    }
    const Vector3 target(preferred[0], preferred[1], preferred[2]);
    if (!target.allFinite())
      throw BadInput{ "preferred velocity must be finite" };
    writeSolution(magna_orca::solveVelocity(rows, max_speed, target), velocity, feasible);
  });
}

}  // extern "C"
