// A minimal UAL-shaped server written against the C++ generated types, the way
// GRVC's own server is: take_off, land, go_to_waypoint and set_home services,
// state and pose topics under the node's namespace (launch it in /uav_1/ual).
// It moves instantly; it exists to prove the wire types, not to fly.
#include <geometry_msgs/PoseStamped.h>
#include <ros/ros.h>
#include <uav_abstraction_layer/GoToWaypoint.h>
#include <uav_abstraction_layer/Land.h>
#include <uav_abstraction_layer/SetHome.h>
#include <uav_abstraction_layer/State.h>
#include <uav_abstraction_layer/TakeOff.h>

namespace ual = uav_abstraction_layer;

class ReferenceServer {
 public:
  explicit ReferenceServer(ros::NodeHandle& nh) {
    pose_.header.frame_id = "map";
    pose_.pose.orientation.w = 1.0;
    state_.state = ual::State::LANDED_ARMED;
    state_pub_ = nh.advertise<ual::State>("state", 10);
    pose_pub_ = nh.advertise<geometry_msgs::PoseStamped>("pose", 10);
    services_.push_back(nh.advertiseService("take_off", &ReferenceServer::takeOff, this));
    services_.push_back(nh.advertiseService("land", &ReferenceServer::land, this));
    services_.push_back(nh.advertiseService("go_to_waypoint", &ReferenceServer::goTo, this));
    services_.push_back(nh.advertiseService("set_home", &ReferenceServer::setHome, this));
    timer_ = nh.createTimer(ros::Duration(1.0 / 30.0), &ReferenceServer::publish, this);
  }

 private:
  bool takeOff(ual::TakeOff::Request& req, ual::TakeOff::Response&) {
    if (state_.state != ual::State::LANDED_ARMED) return false;  // UAL refuses take-off unless landed
    pose_.pose.position.z = req.height;
    state_.state = ual::State::FLYING_AUTO;
    return true;
  }
  bool land(ual::Land::Request&, ual::Land::Response&) {
    if (state_.state != ual::State::FLYING_AUTO) return false;
    pose_.pose.position.z = 0.0;
    state_.state = ual::State::LANDED_ARMED;
    return true;
  }
  bool goTo(ual::GoToWaypoint::Request& req, ual::GoToWaypoint::Response&) {
    if (state_.state != ual::State::FLYING_AUTO) return false;
    pose_.pose = req.waypoint.pose;
    return true;
  }
  bool setHome(ual::SetHome::Request&, ual::SetHome::Response&) { return true; }
  void publish(const ros::TimerEvent&) {
    pose_.header.stamp = ros::Time::now();
    state_pub_.publish(state_);
    pose_pub_.publish(pose_);
  }

  ual::State state_;
  geometry_msgs::PoseStamped pose_;
  ros::Publisher state_pub_, pose_pub_;
  std::vector<ros::ServiceServer> services_;
  ros::Timer timer_;
};

int main(int argc, char** argv) {
  ros::init(argc, argv, "ual");
  ros::NodeHandle nh("~");
  ReferenceServer server(nh);
  ros::spin();
  return 0;
}
