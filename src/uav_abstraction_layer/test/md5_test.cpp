// The checksums below are those of GRVC UAL v3; a mismatch means a real UAL
// server and MAGNA would refuse to talk to each other.
#include <gtest/gtest.h>
#include <ros/message_traits.h>
#include <ros/service_traits.h>
#include <uav_abstraction_layer/State.h>
#include <uav_abstraction_layer/TakeOff.h>
#include <uav_abstraction_layer/Land.h>
#include <uav_abstraction_layer/GoToWaypoint.h>
#include <uav_abstraction_layer/GoToWaypointGeo.h>
#include <uav_abstraction_layer/SetHome.h>

namespace ual = uav_abstraction_layer;

TEST(UalMd5, MessageMatchesGrvc) {
  EXPECT_STREQ("533576484916e98b63315c3434a12ab9", ros::message_traits::MD5Sum<ual::State>::value());
}

TEST(UalMd5, ServicesMatchGrvc) {
  EXPECT_STREQ("92f7691c5527d6fb3cc35d20a69e7778", ros::service_traits::MD5Sum<ual::TakeOff>::value());
  EXPECT_STREQ("c37d0c321494079f6ac6aae0680a10e1", ros::service_traits::MD5Sum<ual::Land>::value());
  EXPECT_STREQ("1b4a030ed9ba0e5a2761567aa99a96b7", ros::service_traits::MD5Sum<ual::GoToWaypoint>::value());
  EXPECT_STREQ("a636a108541a3b824065d8407258fbe8", ros::service_traits::MD5Sum<ual::GoToWaypointGeo>::value());
  EXPECT_STREQ("27f767d7f04b6ba462fa116e03c0b202", ros::service_traits::MD5Sum<ual::SetHome>::value());
}

TEST(UalState, ConstantsInGrvcOrder) {
  EXPECT_EQ(0, ual::State::UNINITIALIZED);
  EXPECT_EQ(2, ual::State::LANDED_ARMED);
  EXPECT_EQ(4, ual::State::FLYING_AUTO);
  EXPECT_EQ(6, ual::State::LANDING);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
