#include "magna_orca_cpp/service_conversion.h"

#include <cmath>
#include <cstdint>
#include <exception>
#include <iomanip>
#include <sstream>
#include <unordered_map>

#include <xmlrpcpp/XmlRpcValue.h>

#include "magna_orca_cpp/orca3d.h"
#include "magna_orca_cpp/validation.h"

namespace magna_orca
{
namespace service
{
namespace
{
// Every private parameter the node reads, for --help and for catching misspelt names.
struct ParameterDoc
{
  const char* name;
  const char* type;
  const char* meaning;
};

const ParameterDoc kParameters[] = {
  { "N_neighbors_aware", "int", "neighbours each agent avoids, nearest first" },
  { "timeStep", "double", "s, step used to push apart agents that already overlap" },
  { "neighborDist", "double", "m, largest gap between surfaces that is looked at" },
  { "timeHorizon", "double", "s, how far ahead velocities are kept collision-free" },
  { "agent_radius", "double", "m, radius of agents that give 0" },
  { "maxSpeed", "double", "m/s, speed limit of agents that give 0" },
  { "max_neighbors", "int", "cap on N_neighbors_aware and on the neighbours of one request" },
  { "max_agents", "int", "cap on the agents of one batch and on the problems of one many-call" },
};

std::string defaultOf(const std::string& name, const Settings& defaults)
{
  const Params& p = defaults.params;
  if (name == "N_neighbors_aware")
    return std::to_string(p.max_neighbors);
  if (name == "timeStep")
    return formatNumber(p.time_step);
  if (name == "neighborDist")
    return formatNumber(p.neighbor_dist);
  if (name == "timeHorizon")
    return formatNumber(p.time_horizon);
  if (name == "agent_radius")
    return formatNumber(p.agent_radius);
  if (name == "maxSpeed")
    return formatNumber(p.max_speed);
  if (name == "max_neighbors")
    return std::to_string(defaults.max_neighbors);
  return std::to_string(defaults.max_agents);
}

std::string describe(const XmlRpc::XmlRpcValue& value)
{
  std::ostringstream text;
  switch (value.getType())
  {
    case XmlRpc::XmlRpcValue::TypeString:
      text << "the string '" << static_cast<const std::string&>(value) << "'";
      break;
    case XmlRpc::XmlRpcValue::TypeBoolean:
      text << "the boolean " << (static_cast<const bool&>(value) ? "true" : "false");
      break;
    case XmlRpc::XmlRpcValue::TypeArray:
      text << "a list";
      break;
    case XmlRpc::XmlRpcValue::TypeStruct:
      text << "a dictionary";
      break;
    default:
      value.write(text);
  }
  return text.str();
}

// An int parameter >= `minimum`; absent keeps `out`.
std::string readCount(const ros::NodeHandle& nh, const std::string& name, int minimum, std::size_t& out)
{
  XmlRpc::XmlRpcValue value;
  if (!nh.getParam(name, value))
    return "";
  if (value.getType() != XmlRpc::XmlRpcValue::TypeInt || static_cast<const int&>(value) < minimum)
    return "~" + name + " is " + describe(value) + ": give a whole number >= " + std::to_string(minimum);
  out = static_cast<std::size_t>(static_cast<const int&>(value));
  return "";
}

// A number parameter (ints accepted); absent keeps `out`. Ranges are checkSettings' job.
std::string readNumber(const ros::NodeHandle& nh, const std::string& name, double& out)
{
  XmlRpc::XmlRpcValue value;
  if (!nh.getParam(name, value))
    return "";
  if (value.getType() == XmlRpc::XmlRpcValue::TypeDouble)
    out = static_cast<const double&>(value);
  else if (value.getType() == XmlRpc::XmlRpcValue::TypeInt)
    out = static_cast<const int&>(value);
  else
    return "~" + name + " is " + describe(value) + ": give a number";
  return "";
}

// `count` entries of `field` against the server's cap `limit` named `setting`.
std::string checkCount(std::size_t count, std::size_t limit, const std::string& field, const char* setting,
                       const char* per)
{
  if (count <= limit)
    return "";
  return field + " has " + std::to_string(count) + " entries: this server takes at most " +
         std::to_string(limit) + " " + per + " (" + setting + "); send fewer or raise " + setting;
}

// The first id that repeats an earlier one, as "<where>.id <id> repeats <earlier>.id: ...".
template <typename NameOf>
std::string firstRepeatedId(const std::vector<std::uint32_t>& ids, NameOf name_of)
{
  std::unordered_map<std::uint32_t, std::size_t> seen;
  seen.reserve(ids.size());
  for (std::size_t i = 0; i < ids.size(); ++i)
  {
    const auto inserted = seen.emplace(ids[i], i);
    if (!inserted.second)
      return name_of(i) + ".id " + std::to_string(ids[i]) + " repeats " + name_of(inserted.first->second) +
             ".id: give every agent of a request its own id";
  }
  return "";
}

std::string indexed(const std::string& name, std::size_t i)
{
  return name + "[" + std::to_string(i) + "]";
}

const char* source(bool from_server)
{
  return from_server ? "server parameters" : "request parameters";
}

// One agent against its neighbours, checked and solved: the code path of both
// /compute_velocity and each problem of /compute_velocity_many, so their answers are the
// same bit for bit. Fields are named under `where` ("" for the one-agent request,
// "problems[3]." in a many-call). Returns "" with `solution` set, or the refusal.
std::string solveProblem(const magna_msgs::OrcaAgent& agent, const std::vector<magna_msgs::OrcaAgent>& neighbors,
                         const magna_msgs::OrcaParams& params_msg, const Settings& settings, const std::string& where,
                         Workspace& work, std::vector<Agent>& others, Solution& solution, bool& from_server)
{
  std::string error = checkCount(neighbors.size(), settings.max_neighbors, where + "neighbors", "~max_neighbors",
                                 where.empty() ? "per request" : "per problem");
  Params params;
  if (error.empty())
    error = resolveParams(params_msg, settings, params, from_server, where + "params");
  Agent self;
  if (error.empty())
  {
    self = toAgent(agent);
    error = checkAgent(self, params, where + "agent");
  }
  others.clear();
  for (std::size_t i = 0; error.empty() && i < neighbors.size(); ++i)
  {
    others.push_back(toAgent(neighbors[i]));
    error = checkAgent(others.back(), params, indexed(where + "neighbors", i));
  }
  if (error.empty())
  {
    std::vector<std::uint32_t> ids{ agent.id };
    for (const magna_msgs::OrcaAgent& neighbor : neighbors)
      ids.push_back(neighbor.id);
    error = firstRepeatedId(ids, [&where](std::size_t i) {
      return i == 0 ? where + "agent" : indexed(where + "neighbors", i - 1);
    });
  }
  if (!error.empty())
    return error;

  solution = newVelocity(self, others, params, work);
  if (!solution.velocity.allFinite())
    return "internal error: the solver gave a non-finite velocity for " +
           (where.empty() ? "" : where.substr(0, where.size() - 1) + ", ") + "agent " + std::to_string(agent.id) + "; please report this request";
  return "";
}
}  // namespace

std::string usage(const std::string& program)
{
  const Settings defaults;
  std::ostringstream text;
  text << "Usage: " << program << " [--help] [ROS remappings, e.g. __name:=orca3d _timeHorizon:=4.0]\n\n"
       << "Serves ORCA-3D (reciprocal collision avoidance in 3D) velocities:\n"
       << "  " << kComputeVelocityService
       << "    magna_msgs/OrcaComputeVelocity: one agent and its neighbours -> its new velocity\n"
       << "  " << kComputeVelocitiesService
       << "  magna_msgs/OrcaComputeVelocities: every agent against the others -> one velocity each, same order\n"
       << "  " << kComputeVelocityManyService
       << "  magna_msgs/OrcaComputeVelocityMany: independent one-agent problems, each solved as\n"
       << "      " << kComputeVelocityService << " would solve it -> one velocity each, same order\n"
       << "Every name can be remapped. A request whose params block is all zero is solved with the\n"
       << "parameters below; otherwise with its own, checked against ~max_neighbors (in a many-call,\n"
       << "each problem's block on its own).\n\n"
       << "Private parameters (type, default, meaning):\n";
  for (const ParameterDoc& parameter : kParameters)
    text << "  ~" << std::left << std::setw(19) << parameter.name << std::setw(8) << parameter.type << std::setw(11)
         << defaultOf(parameter.name, defaults) << parameter.meaning << "\n";
  text << "\nA bad parameter stops the node with exit status 2; bad requests get success=false and a\n"
       << "message naming the field.\n";
  return text.str();
}

CommandLine parseCommandLine(int argc, const char* const* argv)
{
  CommandLine line;
  for (int i = 1; i < argc; ++i)
  {
    const std::string arg = argv[i];
    if (arg == "-h" || arg == "--help")
      line.help = true;
    else if (arg.find(":=") == std::string::npos && line.error.empty())
      line.error = "orca3d_server: unknown argument '" + arg +
                   "': the node takes --help and ROS remappings (name:=value, _param:=value) only";
  }
  return line;
}

std::string checkSettings(const Settings& settings)
{
  if (settings.max_neighbors < 1)
    return "~max_neighbors is 0: give a whole number >= 1";
  if (settings.max_agents < 1)
    return "~max_agents is 0: give a whole number >= 1";
  return checkParams(settings.params, settings.max_neighbors, serverParamNames());
}

std::string readSettings(const ros::NodeHandle& private_nh, Settings& settings)
{
  XmlRpc::XmlRpcValue all;
  if (private_nh.getParam(private_nh.getNamespace(), all) && all.getType() == XmlRpc::XmlRpcValue::TypeStruct)
  {
    for (auto it = all.begin(); it != all.end(); ++it)
    {
      bool known = false;
      for (const ParameterDoc& parameter : kParameters)
        known = known || it->first == parameter.name;
      if (!known)
      {
        std::string names;
        for (const ParameterDoc& parameter : kParameters)
          names += std::string(names.empty() ? "" : ", ") + "~" + parameter.name;
        return "~" + it->first + " is not a parameter of orca3d_server: rename or remove it (known: " + names + ")";
      }
    }
  }
  std::string error;
  Params& p = settings.params;
  if (!(error = readCount(private_nh, "max_neighbors", 1, settings.max_neighbors)).empty() ||
      !(error = readCount(private_nh, "max_agents", 1, settings.max_agents)).empty() ||
      !(error = readCount(private_nh, "N_neighbors_aware", 0, p.max_neighbors)).empty() ||
      !(error = readNumber(private_nh, "timeStep", p.time_step)).empty() ||
      !(error = readNumber(private_nh, "neighborDist", p.neighbor_dist)).empty() ||
      !(error = readNumber(private_nh, "timeHorizon", p.time_horizon)).empty() ||
      !(error = readNumber(private_nh, "agent_radius", p.agent_radius)).empty() ||
      !(error = readNumber(private_nh, "maxSpeed", p.max_speed)).empty())
    return error;
  return checkSettings(settings);
}

Agent toAgent(const magna_msgs::OrcaAgent& msg)
{
  Agent agent;
  agent.position = Vector3(msg.position.x, msg.position.y, msg.position.z);
  agent.velocity = Vector3(msg.velocity.x, msg.velocity.y, msg.velocity.z);
  agent.preferred_velocity = Vector3(msg.preferred_velocity.x, msg.preferred_velocity.y, msg.preferred_velocity.z);
  agent.radius = msg.radius;
  agent.max_speed = msg.max_speed;
  agent.cooperative = !msg.non_cooperative;
  return agent;
}

Params toParams(const magna_msgs::OrcaParams& msg)
{
  Params params;
  params.max_neighbors = msg.n_neighbors_aware;
  params.time_step = msg.time_step;
  params.neighbor_dist = msg.neighbor_dist;
  params.time_horizon = msg.time_horizon;
  params.agent_radius = msg.agent_radius;
  params.max_speed = msg.max_speed;
  return params;
}

geometry_msgs::Vector3 toMsg(const Vector3& vector)
{
  geometry_msgs::Vector3 msg;
  msg.x = vector.x();
  msg.y = vector.y();
  msg.z = vector.z();
  return msg;
}

bool isUnset(const magna_msgs::OrcaParams& msg)
{
  return msg.n_neighbors_aware == 0 && msg.time_step == 0.0 && msg.neighbor_dist == 0.0 &&
         msg.time_horizon == 0.0 && msg.agent_radius == 0.0 && msg.max_speed == 0.0;
}

std::string resolveParams(const magna_msgs::OrcaParams& msg, const Settings& settings, Params& params,
                          bool& from_server, const std::string& where)
{
  from_server = isUnset(msg);
  if (from_server)
  {
    params = settings.params;
    return "";
  }
  params = toParams(msg);
  return magna_orca::checkParams(params, settings.max_neighbors, where);
}

void computeVelocity(const magna_msgs::OrcaComputeVelocity::Request& req,
                     magna_msgs::OrcaComputeVelocity::Response& res, const Settings& settings)
{
  res = magna_msgs::OrcaComputeVelocity::Response();
  try
  {
    Workspace work;
    std::vector<Agent> others;
    Solution solution;
    bool from_server = false;
    const std::string error =
        solveProblem(req.agent, req.neighbors, req.params, settings, "", work, others, solution, from_server);
    if (!error.empty())
    {
      res.message = error;
      return;
    }
    res.velocity = toMsg(solution.velocity);
    res.feasible = solution.feasible;
    res.success = true;
    std::ostringstream message;
    message << "ok: agent " << req.agent.id;
    if (req.agent.non_cooperative)
      message << " is non-cooperative and keeps its preferred velocity";
    else
      message << " against " << req.neighbors.size() << (req.neighbors.size() == 1 ? " neighbour" : " neighbours")
              << " with " << source(from_server)
              << (solution.feasible ? "" : "; infeasible, the least-violating velocity is given");
    res.message = message.str();
  }
  catch (const std::exception& e)
  {
    res = magna_msgs::OrcaComputeVelocity::Response();
    res.message = std::string("internal error: ") + e.what();
  }
  catch (...)
  {
    res = magna_msgs::OrcaComputeVelocity::Response();
    res.message = "internal error: an unknown exception";
  }
}

void computeVelocities(const magna_msgs::OrcaComputeVelocities::Request& req,
                       magna_msgs::OrcaComputeVelocities::Response& res, const Settings& settings)
{
  res = magna_msgs::OrcaComputeVelocities::Response();
  try
  {
    std::string error = checkCount(req.agents.size(), settings.max_agents, "agents", "~max_agents", "per batch");
    Params params;
    bool from_server = false;
    if (error.empty())
      error = resolveParams(req.params, settings, params, from_server);
    std::vector<Agent> agents;
    agents.reserve(error.empty() ? req.agents.size() : 0);
    for (std::size_t i = 0; error.empty() && i < req.agents.size(); ++i)
    {
      agents.push_back(toAgent(req.agents[i]));
      error = checkAgent(agents.back(), params, indexed("agents", i));
    }
    if (error.empty())
    {
      std::vector<std::uint32_t> ids;
      ids.reserve(req.agents.size());
      for (const magna_msgs::OrcaAgent& agent : req.agents)
        ids.push_back(agent.id);
      error = firstRepeatedId(ids, [](std::size_t i) { return indexed("agents", i); });
    }
    if (!error.empty())
    {
      res.message = error;
      return;
    }

    const std::vector<Solution> solutions = newVelocities(agents, params);
    if (solutions.size() != agents.size())
    {
      res.message = "internal error: the solver gave " + std::to_string(solutions.size()) + " velocities for " +
                    std::to_string(agents.size()) + " agents; please report this request";
      return;
    }
    std::size_t infeasible = 0;
    res.velocities.reserve(solutions.size());
    res.feasible.reserve(solutions.size());
    for (std::size_t i = 0; i < solutions.size(); ++i)
    {
      if (!solutions[i].velocity.allFinite())
      {
        res = magna_msgs::OrcaComputeVelocities::Response();
        res.message = "internal error: the solver gave a non-finite velocity for agents[" + std::to_string(i) +
                      "] (id " + std::to_string(req.agents[i].id) + "); please report this request";
        return;
      }
      res.velocities.push_back(toMsg(solutions[i].velocity));
      res.feasible.push_back(solutions[i].feasible);
      infeasible += solutions[i].feasible ? 0 : 1;
    }
    res.success = true;
    std::ostringstream message;
    message << "ok: " << agents.size() << " agents with " << source(from_server) << ", ";
    if (infeasible == 0)
      message << "all feasible";
    else
      message << infeasible << " infeasible (least-violating velocities given)";
    res.message = message.str();
  }
  catch (const std::exception& e)
  {
    res = magna_msgs::OrcaComputeVelocities::Response();
    res.message = std::string("internal error: ") + e.what();
  }
  catch (...)
  {
    res = magna_msgs::OrcaComputeVelocities::Response();
    res.message = "internal error: an unknown exception";
  }
}

void computeVelocityMany(const magna_msgs::OrcaComputeVelocityMany::Request& req,
                         magna_msgs::OrcaComputeVelocityMany::Response& res, const Settings& settings)
{
  res = magna_msgs::OrcaComputeVelocityMany::Response();
  try
  {
    const std::string error =
        checkCount(req.problems.size(), settings.max_agents, "problems", "~max_agents", "per call");
    if (!error.empty())
    {
      res.message = error;
      return;
    }
    Workspace work;  // one for every problem: the solver clears what it reuses
    std::vector<Agent> others;
    std::size_t infeasible = 0;
    res.velocities.reserve(req.problems.size());
    res.feasible.reserve(req.problems.size());
    for (std::size_t i = 0; i < req.problems.size(); ++i)
    {
      const magna_msgs::OrcaProblem& problem = req.problems[i];
      Solution solution;
      bool from_server = false;
      const std::string refusal = solveProblem(problem.agent, problem.neighbors, problem.params, settings,
                                               indexed("problems", i) + ".", work, others, solution, from_server);
      if (!refusal.empty())  // one bad problem refuses the call: no partial answers
      {
        res = magna_msgs::OrcaComputeVelocityMany::Response();
        res.message = refusal;
        return;
      }
      res.velocities.push_back(toMsg(solution.velocity));
      res.feasible.push_back(solution.feasible);
      infeasible += solution.feasible ? 0 : 1;
    }
    res.success = true;
    std::ostringstream message;
    message << "ok: " << req.problems.size() << (req.problems.size() == 1 ? " problem, " : " problems, ");
    if (infeasible == 0)
      message << "all feasible";
    else
      message << infeasible << " infeasible (least-violating velocities given)";
    res.message = message.str();
  }
  catch (const std::exception& e)
  {
    res = magna_msgs::OrcaComputeVelocityMany::Response();
    res.message = std::string("internal error: ") + e.what();
  }
  catch (...)
  {
    res = magna_msgs::OrcaComputeVelocityMany::Response();
    res.message = "internal error: an unknown exception";
  }
}

}  // namespace service
}  // namespace magna_orca
