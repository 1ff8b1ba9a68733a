// The few value types every part of ORCA-3D shares.
#pragma once

#include <cstddef>

#include <Eigen/Core>
#include <Eigen/Geometry>  // cross products

namespace magna_orca
{
using Vector3 = Eigen::Vector3d;

// One agent as ORCA-3D sees it: a sphere that moves. Non-cooperative agents (static
// obstacles, UAVs that do not avoid) keep their course; whoever meets them takes the
// whole avoidance instead of half.
struct Agent
{
  Vector3 position = Vector3::Zero();
  Vector3 velocity = Vector3::Zero();
  Vector3 preferred_velocity = Vector3::Zero();
  double radius = 0.0;     // 0 takes Params::agent_radius
  double max_speed = 0.0;  // 0 takes Params::max_speed
  bool cooperative = true;
};

// Solver parameters, named after the mission's algorithm_control keys.
struct Params
{
  std::size_t max_neighbors = 10;  // N_neighbors_aware
  double time_step = 1.0 / 60.0;   // timeStep (s): used when two agents already overlap
  double neighbor_dist = 6.0;      // neighborDist (m): largest gap between surfaces that is looked at
  double time_horizon = 5.0;       // timeHorizon (s): how far ahead velocities are kept collision-free
  double agent_radius = 0.5;       // agent_radius (m): radius of agents that give none
  double max_speed = 2.0;          // maxSpeed (m/s): speed limit of agents that give none
};

// A closed half-space of velocities {v : normal . (v - point) >= 0}; normal has unit length.
struct Plane
{
  Vector3 point = Vector3::Zero();
  Vector3 normal = Vector3::UnitX();
};

struct Solution
{
  Vector3 velocity = Vector3::Zero();
  bool feasible = true;  // false: no velocity met every half-space; the least violating one is given
};

}  // namespace magna_orca
