// actionlib's C++ SimpleActionClient against MAGNA's Python SimpleActionServer
// (test/take_off_server_rostest.py): the wire protocol, not only the Python API,
// must match actionlib's for C++ nodes to use MAGNA's action servers.
#include <actionlib/client/simple_action_client.h>
#include <gtest/gtest.h>
#include <magna_msgs/TakeOffAction.h>
#include <ros/ros.h>

#include <atomic>
#include <string>

namespace {

using Client = actionlib::SimpleActionClient<magna_msgs::TakeOffAction>;
using State = actionlib::SimpleClientGoalState;

const char* const kAction = "/sa_interop/take_off";
const ros::Duration kWait(20.0);  // a guard against hangs, not a performance expectation

magna_msgs::TakeOffGoal takeOff(float height) {
  magna_msgs::TakeOffGoal goal;
  goal.height = height;
  return goal;
}

TEST(CppClientInterop, GoalSucceedsWithOutcome) {
  Client client(kAction, true);
  ASSERT_TRUE(client.waitForServer(kWait));
  client.sendGoal(takeOff(2.5f));
  ASSERT_TRUE(client.waitForResult(kWait));
  EXPECT_EQ(State::SUCCEEDED, client.getState().state_);
  ASSERT_TRUE(client.getResult() != nullptr);
  EXPECT_EQ("reached 2.50", client.getResult()->outcome);
  EXPECT_EQ("ok", client.getResult()->message);
}

TEST(CppClientInterop, RefusedGoalIsAborted) {
  Client client(kAction, true);
  ASSERT_TRUE(client.waitForServer(kWait));
  client.sendGoal(takeOff(-1.0f));
  ASSERT_TRUE(client.waitForResult(kWait));
  EXPECT_EQ(State::ABORTED, client.getState().state_);
  EXPECT_EQ("height must be positive", client.getState().getText());
  EXPECT_EQ("refused", client.getResult()->outcome);
}

TEST(CppClientInterop, CancelPreemptsARunningGoal) {
  Client client(kAction, true);
  ASSERT_TRUE(client.waitForServer(kWait));
  std::atomic<int> active{0};
  std::atomic<int> feedbacks{0};
  std::atomic<float> target_z{0.0f};
  client.sendGoal(
      takeOff(100.0f),  // held by the server until preempted
      Client::SimpleDoneCallback(), [&active]() { ++active; },
      [&feedbacks, &target_z](const magna_msgs::TakeOffFeedbackConstPtr& feedback) {
        target_z = feedback->current_target.z;
        ++feedbacks;
      });
  const ros::Time deadline = ros::Time::now() + kWait;
  while (feedbacks == 0 && ros::Time::now() < deadline) {
    ros::Duration(0.01).sleep();
  }
  ASSERT_GT(feedbacks, 0) << "no feedback from the running goal";
  EXPECT_FLOAT_EQ(100.0f, target_z);
  EXPECT_EQ(1, active);
  EXPECT_EQ(State::ACTIVE, client.getState().state_);
  client.cancelGoal();
  ASSERT_TRUE(client.waitForResult(kWait));
  EXPECT_EQ(State::PREEMPTED, client.getState().state_);
  EXPECT_EQ("canceled", client.getState().getText());
  EXPECT_EQ("preempted", client.getResult()->outcome);
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "cpp_action_client");
  ros::NodeHandle node;  // keeps the node up for the whole run
  return RUN_ALL_TESTS();
}
