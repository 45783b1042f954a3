#!/usr/bin/env bash
# Soak and resident memory of the whole daemon (docs/benchmarks.md "Soak and memory"): noisemond on the virtual engine through
# drivers, rings, processing and LCM publishing over real multicast in a private network namespace (root).
#   1. real time: the default configuration for REALTIME_S seconds; resident memory (VmRSS, and its peak VmHWM).
#   2. soak: the virtual engine unpaced ([sim] paced = false: as fast as the processing takes it, nothing lost to
#      the pace) for CYCLES cycles; resident memory at start, middle and end, and every counter of the last status.
# Usage: soak.sh BUILD_DIR [CYCLES=1000000] [REALTIME_S=20]
set -euo pipefail
build="$(cd "${1:?usage: $0 BUILD_DIR [CYCLES] [REALTIME_S]}" && pwd)"
cycles="${2:-1000000}"
realtime_s="${3:-20}"
if [ "$(id -u)" -ne 0 ]; then echo "soak.sh: needs root for a private network namespace (unshare -n)" >&2; exit 77; fi
if [ -z "${NOISEMON_SOAK_IN_NS:-}" ]; then
  exec env NOISEMON_SOAK_IN_NS=1 unshare -n bash "$0" "$build" "$cycles" "$realtime_s"
fi
ip link set lo up
ip route add 224.0.0.0/4 dev lo
url="udpm://239.255.76.67:7667?ttl=0"
work="$(mktemp -d)"
trap 'kill $(jobs -p) 2>/dev/null || true; rm -rf "$work"' EXIT

rss_mb() { awk -v k="$2" '$1 == k":" { printf "%.1f", $2 / 1024 }' "/proc/$1/status" 2>/dev/null || echo "?"; }
published() { grep -o 'published=[0-9]*' "$work/status.txt" 2>/dev/null | tail -1 | cut -d= -f2 || true; }

echo "== real time: the simulated engine at its default pace, ${realtime_s} s"
"$build/daemon/noisemond" --lcm "$url" >/dev/null 2>"$work/rt.log" &
pid=$!
sleep "$realtime_s"
echo "resident memory at real time: VmRSS $(rss_mb $pid VmRSS) MB, peak VmHWM $(rss_mb $pid VmHWM) MB"
kill -TERM $pid
wait $pid

echo "== soak: ${cycles} cycles unpaced"
printf '[sim]\npaced = false\n' >"$work/soak.toml"
"$build/daemon/noisemon" watch --status --lcm "$url" >"$work/status.txt" &
watch=$!
sleep 0.3
start=$(date +%s)
"$build/daemon/noisemond" --config "$work/soak.toml" --lcm "$url" --cycles "$cycles" >/dev/null 2>"$work/soak.log" &
pid=$!
marks=(0.02 0.5 0.95)
names=(start middle end)
next=0
while kill -0 $pid 2>/dev/null; do
  sleep 2
  n=$(published); n=${n:-0}
  if [ "$next" -lt 3 ] && awk -v n="$n" -v c="$cycles" -v m="${marks[$next]}" 'BEGIN { exit !(n >= m * c) }'; then
    echo "${names[$next]}: cycle $n after $(( $(date +%s) - start )) s, VmRSS $(rss_mb $pid VmRSS) MB"
    next=$((next + 1))
  fi
done
wait $pid && status=0 || status=$?
elapsed=$(( $(date +%s) - start ))
sleep 1.5
kill -INT $watch 2>/dev/null || true
wait $watch 2>/dev/null || true
echo "daemon exit status $status after ${elapsed} s ($(awk -v c="$cycles" -v s="$elapsed" -v d=$((120000000/3050)) 'BEGIN { printf "%.0f", c * d / 1e6 / (s > 0 ? s : 1) }')x real time)"
echo "last status:"
grep -A3 '^status' "$work/status.txt" | tail -4
