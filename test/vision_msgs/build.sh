#!/usr/bin/env bash
# Build this test-only vision_msgs into a venv (make test does, once): ./build.sh VENV BUILD_DIR [SOURCE]
# SOURCE: another test-only message package to build the same way (../tf2_msgs); default this one.
# Needs cmake, g++ and make (Debian); about a minute on two cores.
set -euo pipefail
tools=$(cd "$(dirname "$0")" && pwd)
here=$(cd "${3:-$tools}" && pwd)
venv=$(realpath "${1:?usage: build.sh VENV BUILD_DIR [SOURCE]}")
build=$(realpath -m "${2:?usage: build.sh VENV BUILD_DIR [SOURCE]}")
python="$venv/bin/python"
mkdir -p "$build"
for tool in cmake g++ make; do
  command -v "$tool" >/dev/null || { echo "build.sh: $tool is missing (apt-get install -y cmake g++ make)" >&2; exit 1; }
done
"$venv/bin/pip" install --quiet -r "$tools/requirements.txt"
includes="$("$python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])');$("$python" -c 'import numpy; print(numpy.get_include())')"
export AMENT_PREFIX_PATH="$venv${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
export CMAKE_PREFIX_PATH="$venv${CMAKE_PREFIX_PATH:+:$CMAKE_PREFIX_PATH}"
export LD_LIBRARY_PATH="$venv/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export PATH="$venv/bin:$PATH" PYTHONNOUSERSITE=1
cmake -S "$here" -B "$build" -DCMAKE_BUILD_TYPE=Release -DCMAKE_INSTALL_PREFIX="$venv" \
  -DPython3_EXECUTABLE="$python" -DPython3_FIND_STRATEGY=LOCATION -DPython3_FIND_VIRTUALENV=ONLY \
  -DPYTHON_INCLUDE_DIRS="$includes" -DBUILD_TESTING=OFF > "$build.log" 2>&1 || { cat "$build.log" >&2; exit 1; }
cmake --build "$build" -j1 >> "$build.log" 2>&1 && cmake --install "$build" >> "$build.log" 2>&1 || { tail -40 "$build.log" >&2; exit 1; }
