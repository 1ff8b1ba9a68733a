// Input checks shared by the service node and the C interface: each returns an empty
// string when the input is usable, otherwise one sentence naming the field and the fix.
#pragma once

#include <cstddef>
#include <string>

#include "magna_orca_cpp/types.h"

namespace magna_orca
{
// `neighbor_limit` caps N_neighbors_aware (the server's ~max_neighbors).
std::string checkParams(const Params& params, std::size_t neighbor_limit, const std::string& where = "params");

// `where` names the agent in the request, e.g. "agent" or "neighbors[3]".
std::string checkAgent(const Agent& agent, const Params& params, const std::string& where);

}  // namespace magna_orca
