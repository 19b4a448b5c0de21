#!/usr/bin/env bash
# `make team-demo`: a local mosquitto (scripts/mosquitto/start_broker.sh), two agents in the
# `market` hall -- uav1 from the start of the path, ugv1 from 12 s along it (--start-time) --
# `kestrel mapd` merging their objects into the team map, and the browser station. Prints the
# station URL, runs for DURATION seconds (default 40) and stops everything, also on Ctrl-C.
#
#   scripts/team_demo.sh [DURATION]      (BUILD_DIR=build by default)
#
# market is rendered once and both agents replay it. mapd's start poses are where each agent
# starts (x, y, z and heading from the rendering's groundtruth.txt), as an operator would
# measure them on the floor; mapd refines them from the objects both agents see.
set -euo pipefail
duration=${1:-40}
root=$(cd "$(dirname "$0")/.." && pwd)
bin=${BUILD_DIR:-$root/build}/kestrel
[[ -x "$bin" ]] || { echo "team_demo.sh: $bin missing (make build)" >&2; exit 1; }
dir=$(mktemp -d "${TMPDIR:-/tmp}/kestrel-team-demo.XXXXXX")
pw=$(head -c 12 /dev/urandom | od -An -tx1 | tr -d ' \n')
pids=()
cleanup() {
  trap - EXIT INT TERM
  # Agents and station first (their last will and final status reach the broker), then mapd
  # (it publishes its last snapshot), then the broker.
  # TERM, not INT: background jobs of a script start with SIGINT ignored. mapd catches TERM and
  # still publishes its last snapshot.
  for p in "${pids[@]}"; do kill -TERM "$p" 2>/dev/null || true; done
  for p in "${pids[@]}"; do wait "$p" 2>/dev/null || true; done
  [[ -f "$dir/broker/pid" ]] && kill "$(cat "$dir/broker/pid")" 2>/dev/null || true
  rm -rf "$dir/market"  # hundreds of MB of frames; the logs and the team map stay
  echo "team-demo: stopped; logs in $dir"
}
trap cleanup EXIT INT TERM

# Not $(...): the broker inherits stdout and would keep the substitution open.
"$root/scripts/mosquitto/start_broker.sh" --dir "$dir/broker" --user "station:$pw" \
  --user "mapd:$pw" --user "uav1:$pw" --user "ugv1:$pw" > "$dir/broker.out" 2> "$dir/broker.err"
port=$(sed -n 's/^port=\([0-9]*\) .*/\1/p' "$dir/broker.out")
ws_port=$(sed -n 's/.* ws_port=\([0-9]*\) .*/\1/p' "$dir/broker.out")
broker="mqtt://127.0.0.1:$port"
export KESTREL_MQTT_PASSWORD=$pw

ugv_start=12
echo "team-demo: rendering market ($((ugv_start + duration)) s) into $dir/market"
"$bin" sim --scenario market --duration "$((ugv_start + duration))" --out "$dir/market" \
  > "$dir/sim.log" 2>&1
# x,y,z,yaw_degrees of the body at time t (TUM: t x y z qx qy qz qw).
start_at() {
  awk -v t="$1" '!/^#/ && $1 >= t - 1e-6 {
    yaw = atan2(2 * ($8 * $7 + $5 * $6), 1 - 2 * ($6 * $6 + $7 * $7)) * 45 / atan2(1, 1)
    printf "%.3f,%.3f,%.3f,%.2f\n", $2, $3, $4, yaw; exit }' "$dir/market/groundtruth.txt"
}
"$bin" mapd --broker "$broker" --agents uav1,ugv1 --start "uav1:$(start_at 0)" \
  --start "ugv1:$(start_at "$ugv_start")" --out "$dir/team" > "$dir/mapd.log" 2>&1 &
pids+=($!)
"$bin" station --broker "$broker" --ws-port "$ws_port" --http 0 --duration 0 \
  > "$dir/station.log" 2>&1 &
pids+=($!)
agent_pids=()
"$bin" agent --id uav1 --role uav --broker "$broker" --source "kestrel:$dir/market" --duration "$duration" \
  --detector oracle --video off > "$dir/uav1.log" 2>&1 &
agent_pids+=($!)
"$bin" agent --id ugv1 --role ugv --broker "$broker" --source "kestrel:$dir/market" --start-time "$ugv_start" \
  --duration "$duration" --detector oracle --video off > "$dir/ugv1.log" 2>&1 &
agent_pids+=($!)
pids=("${agent_pids[@]}" "${pids[@]}")

url=""
for _ in $(seq 100); do
  url=$(grep -o 'http://127.0.0.1:[0-9]*[^ ]*' "$dir/station.log" | head -1 || true)
  [[ -n "$url" ]] && break
  sleep 0.1
done
echo "team-demo: broker $broker (WebSocket $ws_port), user station, password $pw"
echo "team-demo: station page ${url:-(not up; see $dir/station.log)}"
echo "team-demo: agents replay ${duration} s each at sensor rate; mapd log: $dir/mapd.log"
for p in "${agent_pids[@]}"; do wait "$p" || echo "team-demo: an agent exited with $?" >&2; done
sleep 2  # the last object snapshots reach mapd
grep -h '^agent ' "$dir/uav1.log" "$dir/ugv1.log" || true
kill -TERM "${pids[2]}" 2>/dev/null || true  # mapd: final snapshot and summary
wait "${pids[2]}" 2>/dev/null || true
sed -n '/^mapd:/,$p' "$dir/mapd.log"
