// The ROS side of ORCA-3D: the orca3d_server's command line and parameters, message <->
// library conversion, and the request checks and handlers. The node only wires these up;
// the solver library (magna_orca3d) stays free of ROS.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <geometry_msgs/Vector3.h>
#include <magna_msgs/OrcaAgent.h>
#include <magna_msgs/OrcaComputeVelocities.h>
#include <magna_msgs/OrcaComputeVelocity.h>
#include <magna_msgs/OrcaComputeVelocityMany.h>
#include <magna_msgs/OrcaParams.h>
#include <ros/node_handle.h>

#include "magna_orca_cpp/types.h"

namespace magna_orca
{
namespace service
{
// Absolute by default; remap them like any name (`/magna/orca3d/compute_velocity:=/x`).
constexpr const char* kComputeVelocityService = "/magna/orca3d/compute_velocity";
constexpr const char* kComputeVelocitiesService = "/magna/orca3d/compute_velocities";
constexpr const char* kComputeVelocityManyService = "/magna/orca3d/compute_velocity_many";

// What the server runs with: the solver parameters a request gets when its params block
// is all zero, and the caps that keep one request from taking the node down.
struct Settings
{
  Params params;                    // ~N_neighbors_aware ~timeStep ~neighborDist ~timeHorizon ~agent_radius ~maxSpeed
  std::size_t max_neighbors = 1000;  // ~max_neighbors: cap on N_neighbors_aware and on neighbours per request
  std::size_t max_agents = 100000;   // ~max_agents: cap on the agents of one batch and the problems of one many-call
};

// --help text: services, parameters and their defaults.
std::string usage(const std::string& program);

// The command line before ros::init: ROS remappings (anything with ":=") pass through.
struct CommandLine
{
  bool help = false;
  std::string error;  // non-empty: an argument the node does not know (exit status 2)
};
CommandLine parseCommandLine(int argc, const char* const* argv);

// "" when the settings are usable, otherwise one sentence naming the ~parameter and the fix.
std::string checkSettings(const Settings& settings);

// Reads the private parameters over the defaults in `settings` and checks them; returns ""
// or an error naming the parameter (wrong type, out of range).
std::string readSettings(const ros::NodeHandle& private_nh, Settings& settings);

// Message -> library values, field for field (no checks here).
Agent toAgent(const magna_msgs::OrcaAgent& msg);
Params toParams(const magna_msgs::OrcaParams& msg);
geometry_msgs::Vector3 toMsg(const Vector3& vector);

// True when every field of the block is zero: the request asks for the server's parameters.
bool isUnset(const magna_msgs::OrcaParams& msg);

// The parameters a request is solved with: the server's when its block is unset, else its
// own, checked against the server's caps. Returns "" or an error naming the field, which is
// called `where` ("params", or "problems[3].params" in a many-call).
std::string resolveParams(const magna_msgs::OrcaParams& msg, const Settings& settings, Params& params,
                          bool& from_server, const std::string& where = "params");

// The handlers: they always fill `res` and never throw. Bad input gives success=false and
// a message naming the field; an unexpected exception gives success=false and its text.
void computeVelocity(const magna_msgs::OrcaComputeVelocity::Request& req,
                     magna_msgs::OrcaComputeVelocity::Response& res, const Settings& settings);
void computeVelocities(const magna_msgs::OrcaComputeVelocities::Request& req,
                       magna_msgs::OrcaComputeVelocities::Response& res, const Settings& settings);
// Each problem is checked and solved exactly as computeVelocity would (same code, one
// workspace for all), so each answer equals that problem's one-agent answer bit for bit. At
// most ~max_agents problems per call, each with at most ~max_neighbors neighbours; one bad
// problem refuses the call with a message naming it ("problems[3].agent.radius is -1: ...").
void computeVelocityMany(const magna_msgs::OrcaComputeVelocityMany::Request& req,
                         magna_msgs::OrcaComputeVelocityMany::Response& res, const Settings& settings);

}  // namespace service
}  // namespace magna_orca
