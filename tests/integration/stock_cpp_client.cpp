// actionlib's own C++ SimpleActionClient sends ArmMoveJoint goals that the arm services refuse at
// once (joint index 9). It prints one line for each goal that did not end as refused, then
// "<lost> of <goals> lost", and exits 0 only when every goal ended with its refusal.
// Usage: stock_cpp_client <goals>. tests/integration/test_action_refusals.py builds and runs it.
#include <actionlib/client/simple_action_client.h>
#include <owl_msgs/ArmMoveJointAction.h>
#include <ros/ros.h>

#include <cstdio>
#include <cstdlib>
#include <string>

int main(int argc, char** argv) {
  ros::init(argc, argv, "stock_cpp_client", ros::init_options::AnonymousName);
  const int goals = argc > 1 ? std::atoi(argv[1]) : 50;
  actionlib::SimpleActionClient<owl_msgs::ArmMoveJointAction> client("ArmMoveJoint", true);
  if (!client.waitForServer(ros::Duration(600.0))) {  // s of sim time
    std::printf("no ArmMoveJoint server\n");
    return 2;
  }
  int lost = 0;
  for (int k = 0; k < goals; ++k) {
    owl_msgs::ArmMoveJointGoal goal;
    goal.relative = false;
    goal.joint = 9;
    goal.angle = 0.1;
    client.sendGoal(goal);
    if (!client.waitForResult(ros::Duration(100.0))) {  // s of sim time
      std::printf("goal %d did not end\n", k);
      ++lost;
      continue;
    }
    const actionlib::SimpleClientGoalState state = client.getState();
    const bool refused = state == actionlib::SimpleClientGoalState::ABORTED ||
                         state == actionlib::SimpleClientGoalState::REJECTED;
    if (!refused || state.getText().find("joint=9") == std::string::npos) {
      std::printf("goal %d ended %s: %s\n", k, state.toString().c_str(), state.getText().c_str());
      ++lost;
    }
  }
  std::printf("%d of %d lost\n", lost, goals);
  std::fflush(stdout);
  return lost == 0 ? 0 : 1;
}
