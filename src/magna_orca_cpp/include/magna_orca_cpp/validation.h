// Input checks shared by the service node and the C interface: each returns an empty
// string when the input is usable, otherwise one sentence naming the field and the fix.
#pragma once

#include <cstddef>
#include <string>

#include "magna_orca_cpp/types.h"

namespace magna_orca
{
// What the fields of Params are called where an error is reported.
struct ParamNames
{
  std::string max_neighbors, time_step, neighbor_dist, time_horizon, agent_radius, max_speed;
  std::string neighbor_cap;  // the setting that caps max_neighbors, named in the advice
};

// A request's params block as the service message spells it, with the mission's names:
// "params.time_horizon (timeHorizon)".
ParamNames requestParamNames(const std::string& where = "params");
// The server's private parameters: "~timeHorizon".
ParamNames serverParamNames();

// `neighbor_limit` caps N_neighbors_aware (the server's ~max_neighbors).
std::string checkParams(const Params& params, std::size_t neighbor_limit, const ParamNames& names);
std::string checkParams(const Params& params, std::size_t neighbor_limit, const std::string& where = "params");

// `where` names the agent in the request, e.g. "agent" or "neighbors[3]".
std::string checkAgent(const Agent& agent, const Params& params, const std::string& where);

// A number as the messages print it (shortest form; nan, inf, -inf).
std::string formatNumber(double value);

}  // namespace magna_orca
