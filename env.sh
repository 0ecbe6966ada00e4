# Source this file (`source env.sh`) for a shell that can run roscore, rosrun and rosservice call
# against this workspace: the venv, the devel space, a loopback ROS_HOSTNAME and ROS_HOME in here.
_ow_root="$(cd "$(dirname "${BASH_SOURCE[0]:-$0}")" && pwd)"
# shellcheck disable=SC1091
source "$_ow_root/.venv/bin/activate"
# shellcheck disable=SC1091
source "$_ow_root/devel/setup.bash"
export ROS_HOSTNAME=127.0.0.1
export ROS_HOME="$_ow_root/.ros"
export ROS_MASTER_URI="${OW_MASTER_URI:-http://127.0.0.1:11311}"
mkdir -p "$ROS_HOME"
unset _ow_root
