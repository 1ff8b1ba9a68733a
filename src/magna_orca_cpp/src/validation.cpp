#include "magna_orca_cpp/validation.h"

#include <cmath>
#include <sstream>

namespace magna_orca
{
std::string formatNumber(double value)
{
  std::ostringstream text;
  text << value;
  return text.str();
}

namespace
{
std::string checkVector(const Vector3& vector, const std::string& where)
{
  static const char* const kAxes[] = { "x", "y", "z" };
  for (int axis = 0; axis < 3; ++axis)
    if (!std::isfinite(vector[axis]))
      return where + "." + kAxes[axis] + " is " + formatNumber(vector[axis]) + ": give a finite number";
  return "";
}

// A positive, finite parameter.
std::string checkPositive(double value, const std::string& name, const char* unit)
{
  if (!std::isfinite(value) || value <= 0.0)
    return name + " is " + formatNumber(value) + ": give a positive number of " + unit;
  return "";
}

// A finite value >= 0.
std::string checkNotNegative(double value, const std::string& name, const char* what)
{
  if (!std::isfinite(value) || value < 0.0)
    return name + " is " + formatNumber(value) + ": " + what;
  return "";
}
}  // namespace

ParamNames requestParamNames(const std::string& where)
{
  return ParamNames{ where + ".n_neighbors_aware (N_neighbors_aware)",
                     where + ".time_step (timeStep)",
                     where + ".neighbor_dist (neighborDist)",
                     where + ".time_horizon (timeHorizon)",
                     where + ".agent_radius",
                     where + ".max_speed (maxSpeed)",
                     "~max_neighbors" };
}

ParamNames serverParamNames()
{
  return ParamNames{ "~N_neighbors_aware", "~timeStep", "~neighborDist", "~timeHorizon", "~agent_radius", "~maxSpeed",
                     "~max_neighbors" };
}

std::string checkParams(const Params& params, std::size_t neighbor_limit, const ParamNames& names)
{
  if (params.max_neighbors > neighbor_limit)
    return names.max_neighbors + " is " + std::to_string(params.max_neighbors) + ": above the cap of " +
           std::to_string(neighbor_limit) + " neighbours per agent (" + names.neighbor_cap + "); lower it or raise " +
           names.neighbor_cap;
  std::string error;
  if (!(error = checkPositive(params.time_step, names.time_step, "seconds")).empty() ||
      !(error = checkPositive(params.time_horizon, names.time_horizon, "seconds")).empty() ||
      !(error = checkNotNegative(params.neighbor_dist, names.neighbor_dist, "give a finite distance >= 0 (m)"))
           .empty() ||
      !(error = checkNotNegative(params.agent_radius, names.agent_radius,
                                 "give a finite radius >= 0 (m; 0 means every agent gives its own)"))
           .empty() ||
      !(error = checkNotNegative(params.max_speed, names.max_speed,
                                 "give a finite speed >= 0 (m/s; 0 means every agent gives its own)"))
           .empty())
    return error;
  return "";
}

std::string checkParams(const Params& params, std::size_t neighbor_limit, const std::string& where)
{
  return checkParams(params, neighbor_limit, requestParamNames(where));
}

std::string checkAgent(const Agent& agent, const Params& params, const std::string& where)
{
  std::string error;
  if (!(error = checkVector(agent.position, where + ".position")).empty())
    return error;
  if (!(error = checkVector(agent.velocity, where + ".velocity")).empty())
    return error;
  if (!(error = checkVector(agent.preferred_velocity, where + ".preferred_velocity")).empty())
    return error;
  if (!(error = checkNotNegative(agent.radius, where + ".radius",
                                 "give a radius > 0 in metres, or 0 to take params.agent_radius"))
           .empty())
    return error;
  if (!(error = checkNotNegative(agent.max_speed, where + ".max_speed",
                                 "give a speed > 0 in m/s, or 0 to take params.max_speed"))
           .empty())
    return error;
  if (agent.radius == 0.0 && params.agent_radius == 0.0)
    return where + ".radius is 0 and params.agent_radius is 0: give a positive radius in either";
  if (agent.max_speed == 0.0 && params.max_speed == 0.0 && agent.cooperative)
    return where + ".max_speed is 0 and params.max_speed is 0: give a positive speed limit in either";
  return "";
}

}  // namespace magna_orca
