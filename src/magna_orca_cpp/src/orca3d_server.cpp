// orca3d_server: ORCA-3D velocities as ROS services. Thin: the command line, parameters,
// checks and handlers live in service_conversion (see `orca3d_server --help`).
#include <iostream>
#include <string>

#include <ros/ros.h>

#include "magna_orca_cpp/service_conversion.h"

namespace service = magna_orca::service;

int main(int argc, char** argv)
{
  const std::string program = "orca3d_server";
  const service::CommandLine line = service::parseCommandLine(argc, argv);
  if (line.help)
  {
    std::cout << service::usage(program);
    return 0;
  }
  if (!line.error.empty())
  {
    std::cerr << line.error << "\n(" << program << " --help lists the services and parameters)" << std::endl;
    return 2;
  }

  ros::init(argc, argv, program);
  ros::NodeHandle nh;
  ros::NodeHandle private_nh("~");
  service::Settings settings;
  const std::string error = service::readSettings(private_nh, settings);
  if (!error.empty())
  {
    ROS_FATAL_STREAM(ros::this_node::getName() << ": " << error);
    return 2;
  }

  using One = magna_msgs::OrcaComputeVelocity;
  using Batch = magna_msgs::OrcaComputeVelocities;
  using Many = magna_msgs::OrcaComputeVelocityMany;
  const ros::ServiceServer one = nh.advertiseService<One::Request, One::Response>(
      service::kComputeVelocityService, [&settings](One::Request& req, One::Response& res) {
        service::computeVelocity(req, res, settings);
        return true;
      });
  const ros::ServiceServer batch = nh.advertiseService<Batch::Request, Batch::Response>(
      service::kComputeVelocitiesService, [&settings](Batch::Request& req, Batch::Response& res) {
        service::computeVelocities(req, res, settings);
        return true;
      });
  const ros::ServiceServer many = nh.advertiseService<Many::Request, Many::Response>(
      service::kComputeVelocityManyService, [&settings](Many::Request& req, Many::Response& res) {
        service::computeVelocityMany(req, res, settings);
        return true;
      });

  const magna_orca::Params& p = settings.params;
  ROS_INFO_STREAM("ORCA-3D serving " << one.getService() << ", " << batch.getService() << " and "
                                     << many.getService()
                                     << " (N_neighbors_aware " << p.max_neighbors << ", timeStep " << p.time_step
                                     << ", neighborDist " << p.neighbor_dist << ", timeHorizon " << p.time_horizon
                                     << ", agent_radius " << p.agent_radius << ", maxSpeed " << p.max_speed
                                     << ", max_neighbors " << settings.max_neighbors << ", max_agents "
                                     << settings.max_agents << ")");
  ros::spin();
  return 0;
}
