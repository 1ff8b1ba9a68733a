#include "magna_orca_cpp/validation.h"

#include <cmath>
#include <sstream>

namespace magna_orca
{
namespace
{
std::string show(double value)
{
  std::ostringstream text;
  text << value;
  return text.str();
}

std::string checkVector(const Vector3& vector, const std::string& where)
{
  static const char* const kAxes[] = { "x", "y", "z" };
  for (int axis = 0; axis < 3; ++axis)
    if (!std::isfinite(vector[axis]))
      return where + "." + kAxes[axis] + " is " + show(vector[axis]) + ": give a finite number";
  return "";
}

// A positive, finite parameter.
std::string checkPositive(double value, const std::string& where, const char* legacy_name, const char* unit)
{
  if (!std::isfinite(value) || value <= 0.0)
    return where + " (" + legacy_name + ") is " + show(value) + ": give a positive number of " + unit;
  return "";
}

// A finite parameter >= 0.
std::string checkNotNegative(double value, const std::string& where, const char* what)
{
  if (!std::isfinite(value) || value < 0.0)
    return where + " is " + show(value) + ": " + what;
  return "";
}
}  // namespace

std::string checkParams(const Params& params, std::size_t neighbor_limit, const std::string& where)
{
  if (params.max_neighbors > neighbor_limit)
    return where + ".n_neighbors_aware (N_neighbors_aware) is " + std::to_string(params.max_neighbors) +
           ": this solver takes at most " + std::to_string(neighbor_limit) + " neighbours per agent";
  std::string error;
  if (!(error = checkPositive(params.time_step, where + ".time_step", "timeStep", "seconds")).empty())
    return error;
  if (!(error = checkPositive(params.time_horizon, where + ".time_horizon", "timeHorizon", "seconds")).empty())
    return error;
  if (!(error = checkNotNegative(params.neighbor_dist, where + ".neighbor_dist",
                                 "neighborDist must be a finite distance >= 0 (m)"))
           .empty())
    return error;
  if (!(error = checkNotNegative(params.agent_radius, where + ".agent_radius",
                                 "agent_radius must be a finite radius >= 0 (m)"))
           .empty())
    return error;
  return checkNotNegative(params.max_speed, where + ".max_speed", "maxSpeed must be a finite speed >= 0 (m/s)");
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
