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
# Every node is its own Python process: without cached bytecode each one compiles the
# workspace's modules and generated messages again at start-up (0.3 s of CPU per node). The
# cache lives in build/, out of the source tree, also where PYTHONDONTWRITEBYTECODE was set.
unset PYTHONDONTWRITEBYTECODE
export PYTHONPYCACHEPREFIX="$_ow_root/build/pycache"
unset _ow_root
