#!/usr/bin/env bash
# Wall time of the main job split into N shards started side by side, then
# finished by a plain `dropscope run` (docs/cluster.md), for N = 1, 2, 4,
# against the whole job in one process; each figure is the time from the
# first shard's start to the end of the finishing run, into a fresh folder.
#
#   benches/shards.sh RUNS_CSV [REPEATS]
#
# RUNS_CSV: a manifest (e.g. from `dropscope render --campaign`). The
# configuration is the repository's pipeline.toml with that manifest. Shards
# get THREADS_PER_SHARD threads each (default: the cores divided among them,
# at least 1); DROPSCOPE picks the binary (default target/release/dropscope).
# With SLURM=1 the shards are the tasks of `dropscope slurm --array N
# --submit` (cpus-per-task likewise) and the time runs to the finishing
# job's end, Slurm's scheduling included (needs a running Slurm: .ci/slurm-up).
set -euo pipefail
cd "$(dirname "$0")/.."
manifest=$(realpath "$1")
repeats=${2:-3}
bin=$(realpath "${DROPSCOPE:-target/release/dropscope}")
cores=$(nproc)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
sed "s|^manifest = .*|manifest = \"$manifest\"|" pipeline.toml > "$work/pipeline.toml"
cfg="$work/pipeline.toml"

now() { date +%s%N; }
secs() { awk -v ns="$(( $(now) - $1 ))" 'BEGIN { printf "%.2f", ns / 1e9 }'; }
# One timing, "wall s (CPU s)": N shards side by side into a fresh folder,
# then the finishing run. CPU is user + system of every process.
TIMEFORMAT='%R %U %S'
timed() {
  local t
  t=$( { time "$@" >/dev/null 2>&1; } 2>&1 )
  awk -v t="$t" 'BEGIN { split(t, a, " "); printf "%.2f s (CPU %.2f s)", a[1], a[2] + a[3] }'
}
shards_then_finish() {
  local n=$1 out="$work/out" threads=${THREADS_PER_SHARD:-$(( cores / $1 > 0 ? cores / $1 : 1 ))}
  for k in $(seq 0 $((n - 1))); do
    "$bin" run --config "$cfg" --out "$out" --shard "$k/$n" --threads "$threads" &
  done
  wait
  "$bin" run --config "$cfg" --out "$out" --threads "$cores" || [ $? -eq 1 ]
}
sharded() { rm -rf "$work/out"; timed shards_then_finish "$1"; }
# The same through Slurm: submit, then poll the finishing job's state.
through_slurm() {
  local n=$1 out="$work/out" cpus=${THREADS_PER_SHARD:-$(( cores / $1 > 0 ? cores / $1 : 1 ))}
  rm -rf "$out" "$work/out.slurm"
  local t0; t0=$(now)
  local fin
  fin=$("$bin" slurm --config "$cfg" --out "$out" --array "$n" --cpus-per-task "$cpus" --submit \
    | awk '/^finishing job/ { print $3 }')
  until scontrol show job -o "$fin" | grep -qE 'JobState=(COMPLETED|FAILED|CANCELLED|TIMEOUT)'; do
    sleep 0.05
  done
  scontrol show job -o "$fin" | grep -q 'JobState=COMPLETED' || { echo "job $fin failed" >&2; exit 1; }
  printf "%s s" "$(secs "$t0")"
}
whole_job() { "$bin" run --config "$cfg" --out "$work/out" --threads "$cores" || [ $? -eq 1 ]; }
whole() { rm -rf "$work/out"; timed whole_job; }

echo "$(wc -l < "$manifest") manifest lines, $cores cores, load $(cut -d' ' -f1-3 /proc/loadavg)"
for r in $(seq "$repeats"); do
  printf 'round %d: whole %s' "$r" "$(whole)"
  for n in 1 2 4; do
    if [ "${SLURM:-0}" = 1 ]; then t=$(through_slurm "$n"); else t=$(sharded "$n"); fi
    printf ', %d shard(s) %s' "$n" "$t"
  done
  echo
done
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
