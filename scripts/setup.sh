#!/usr/bin/env bash
# Install what this workspace needs and build it. Idempotent: each step checks first and does
# nothing when it is already done, so a second run takes about a second.
#
#   scripts/setup.sh            # apt packages (root, or sudo), .venv with pinned wheels, catkin_make
#   OW_SKIP_YADE=1 scripts/setup.sh   # leave out the optional DEM engine (YADE, ~170 packages)
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD

apt_packages=(
  ros-core catkin ros-message-generation ros-message-runtime rosbash
  python3-rospy python3-rosservice python3-rostest python3-rosbag
  python3-tf2-ros python3-tf2-geometry-msgs
  python3-std-msgs python3-std-srvs python3-geometry-msgs python3-sensor-msgs
  python3-visualization-msgs python3-trajectory-msgs python3-rosgraph-msgs python3-tf2-msgs
  ros-trajectory-msgs ros-sensor-msgs libsensor-msgs-dev python3-roslaunch
  python3-genpy python3-genmsg python3-venv python3-pip g++ make cmake
  # action message generation (owl_msgs): actionlib_msgs' .msg files, cmake macros and Python
  ros-actionlib-msgs libactionlib-msgs-dev python3-actionlib-msgs python3-actionlib
  libgeometry-msgs-dev
  # ow_faults and the simulation's PID gains: dynamic_reconfigure servers, their .cfg generation
  python3-dynamic-reconfigure libdynamic-reconfigure-config-init-mutex-dev
  # ow_viz: RViz, and a virtual X server and ImageMagick's `import` for its screenshot test
  rviz xvfb imagemagick
  # what other Debian Python packages ask for, so that `pip check` in the venv is clean
  python3-cffi python3-cairo
)
[ "${OW_SKIP_YADE:-0}" = 1 ] || apt_packages+=(yade)

missing=()
for p in "${apt_packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${#missing[@]} Debian packages: ${missing[*]}"
  sudo=""
  if [ "$(id -u)" != 0 ]; then
    command -v sudo >/dev/null || { echo "setup: need root or sudo to install: ${missing[*]}" >&2; exit 1; }
    sudo=sudo
  fi
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -q
  if ! $sudo apt-get install -y -q --no-install-recommends "${missing[@]}"; then
    # YADE is optional (DEM table generation); everything else is not.
    if [[ " ${missing[*]} " == *" yade "* ]]; then
      echo "setup: installing without yade (DEM table generation and its smoke test will be skipped)" >&2
      missing=("${missing[@]/yade}")
      $sudo apt-get install -y -q --no-install-recommends ${missing[@]}
    else
      exit 1
    fi
  fi
fi

# The venv must come from Debian's python (the one with rospy), never the python3 on PATH.
if [ ! -x .venv/bin/python ] || ! .venv/bin/python -c 'import rospy' 2>/dev/null; then
  rm -rf .venv
  /usr/bin/python3 -m venv --system-site-packages .venv
fi
# The wheels go in with uv (pinned here): 14 s in a fresh clone against pip's 71 s, most of it
# pip's resolving and bytecode compiling. uv installs every dependency into the venv, where pip
# took some (matplotlib's) from Debian's packages; the stamp names the installer, so a venv that
# pip filled is completed once.
uv_version=0.13.9
installed="$(cat requirements.txt) # installed with uv $uv_version"
if [ "$(cat .venv/.requirements.installed 2>/dev/null)" != "$installed" ]; then
  echo "setup: installing pinned Python wheels into .venv"
  # (grep drops pip's warnings about this machine's extra, empty package indexes)
  .venv/bin/pip install -q --disable-pip-version-check "uv==$uv_version" 2>&1 \
    | { grep -v "is ignored: it is neither a file nor a directory" || true; }
  .venv/bin/uv pip install -q --python .venv/bin/python -r requirements.txt
  echo "$installed" > .venv/.requirements.installed
fi

# Debian's matplotlib (pulled in by yade) declares mpl_toolkits a namespace package rooted in its
# own tree; without this, `mpl_toolkits.mplot3d` resolves to Debian's 3.6 copy and the venv's
# matplotlib warns "Unable to import Axes3D". This .pth runs before the system site's and puts
# the venv's mpl_toolkits first.
pth=$(.venv/bin/python -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')/ow_mpl_toolkits.pth
pth_line="import sys, types, os; m = sys.modules.setdefault('mpl_toolkits', types.ModuleType('mpl_toolkits')); p = os.path.join(sitedir, 'mpl_toolkits'); mp = m.__dict__.setdefault('__path__', []); (p not in mp) and mp.insert(0, p)"
[ "$(cat "$pth" 2>/dev/null)" = "$pth_line" ] || echo "$pth_line" > "$pth"

# catkin_make only when a build input changed since the last build.
stamp=build/.ow_build_stamp
if [ ! -f devel/setup.bash ] || [ ! -f "$stamp" ] || [ -n "$(find src -newer "$stamp" \
     \( -name package.xml -o -name CMakeLists.txt -o -name setup.py -o -name '*.msg' -o -name '*.srv' -o -name '*.action' -o -name '*.cfg' \
        -o -path '*/nodes/*' \) -print -quit)" ]; then
  echo "setup: catkin_make"
  # shellcheck disable=SC1091
  source .venv/bin/activate
  catkin_make -DPYTHON_EXECUTABLE="$root/.venv/bin/python" -DCMAKE_BUILD_TYPE=Release >build.log 2>&1 \
    || { tail -40 build.log >&2; echo "setup: catkin_make failed, full log in build.log" >&2; exit 1; }
  touch "$stamp"
fi
