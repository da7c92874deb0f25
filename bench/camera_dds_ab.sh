#!/usr/bin/env bash
# get_image frames/s through the DDS transport, a DdsClient reading its images raw
# (simgate_bench_dds --mode camera --raw), against a gateway of two builds run alternately:
# what a change to the camera or the transport costs or saves per frame on the render thread.
#   bench/camera_dds_ab.sh BEFORE AFTER [ROUNDS] [COUNT] [WIDTHxHEIGHT] [--png]
# BEFORE and AFTER: build trees (or copies of their bin/, lib/ and plugins/); the client is
# AFTER's simgate_bench_dds. Each round starts BEFORE's gateway, then AFTER's, on a scene of a
# red box in front of a 640x480 camera (by default), measures COUNT calls after COUNT/10, and
# prints a JSON line per run: the client's figures plus the gateway's CPU seconds per frame
# (its user + system time over the client's run, /proc/PID/stat). --png: a client without
# raw_images (the PNG records), to check that nothing changed for it. Loopback only.
set -euo pipefail

before=$(realpath "$1") after=$(realpath "$2") rounds=${3:-5} count=${4:-200} size=${5:-640x480}
raw=--raw
[ "${6:-}" = "--png" ] && raw=
width=${size%x*} height=${size#*x}
work=$(mktemp -d)
gateway_pid=
cleanup() {
  [ -n "$gateway_pid" ] && kill "$gateway_pid" 2>/dev/null && wait "$gateway_pid" 2>/dev/null
  rm -rf "$work"
}
trap cleanup EXIT

cat >"$work/scene.xml" <<'EOF'
<mujoco model="camera-dds-ab">
  <option timestep="0.005"/>
  <visual><headlight ambient="0.4 0.4 0.4" diffuse="0.6 0.6 0.6"/></visual>
  <worldbody>
    <light pos="0 0 5" dir="0 0 -1"/>
    <geom name="floor" type="plane" size="10 10 0.1" rgba="0.5 0.5 0.5 1"/>
    <body name="rig" pos="0 0 0.5">
      <geom type="sphere" size="0.01" contype="0" conaffinity="0" rgba="0 0 1 0"/>
      <camera name="front" xyaxes="0 -1 0 0 0 1" fovy="60"/>
    </body>
    <body name="target" pos="2 0 0.5">
      <geom name="red_box" type="box" size="0.3 0.3 0.3" rgba="1 0 0 1"/>
    </body>
  </worldbody>
</mujoco>
EOF
domain=$((20 + $$ % 200)) partition="camera-ab-$$"
cat >"$work/deployment.json" <<EOF
{"scene": {"mjcf": "$work/scene.xml", "timestep": 0.005, "realtime_factor": 1.0},
 "transports": {"dds": {"plugin": "dds", "options": {"domain": $domain, "partition": "$partition"}}},
 "services": {"default": ["dds"]},
 "robots": [{"name": "rig", "type": "robot", "body": "rig",
             "components": [{"name": "camera", "type": "video_camera",
                             "options": {"camera": "front", "cam_width": $width, "cam_height": $height}}]}]}
EOF

# user + system clock ticks of a process
cpu_ticks() { awk '{print $14 + $15}' "/proc/$1/stat"; }

for round in $(seq 1 "$rounds"); do
  for side in before after; do
    dir=${!side}
    LD_LIBRARY_PATH="$dir/lib" "$dir/bin/simgate" run "$work/deployment.json" --plugin-path "$dir/plugins" \
      >"$work/gateway.log" 2>&1 &
    gateway_pid=$!
    sleep 1
    ticks0=$(cpu_ticks "$gateway_pid")
    result=$(LD_LIBRARY_PATH="$after/lib" "$after/bin/simgate_bench_dds" --mode camera $raw --domain "$domain" \
      --partition "$partition" --count "$count" --warmup $((count / 10)) --timeout 60)
    ticks1=$(cpu_ticks "$gateway_pid")
    kill "$gateway_pid"
    wait "$gateway_pid" 2>/dev/null || true
    gateway_pid=
    cpu_per_frame=$(awk -v t=$((ticks1 - ticks0)) -v hz="$(getconf CLK_TCK)" -v n=$((count + count / 10)) \
      'BEGIN {printf "%.5f", t / hz / n}')
    echo "{\"round\": $round, \"side\": \"$side\", \"gateway_cpu_s_per_frame\": $cpu_per_frame, \"client\": $result}"
  done
done
