#!/usr/bin/env bash
# Model-checks the Feedback Stage's wait/process exchange (exchange.pml, the
# protocol of lib/src/stage/feedback_stage*.cpp) with spin, and shows that the check
# bites: every exchange_broken_*.pml must be rejected.
#
#  - exchange.pml, in every configuration below: a full state-space search for
#    assertion violations (list, inbox and outbox ownership; a cancel reaching
#    its iteration) and invalid end states (deadlocks), with every statement
#    of the model reached; then each ltl property with weak fairness.
#  - exchange_broken_*.pml, in the configuration named on its "spin-flags:"
#    line: the same safety search must report an error.
#
# Usage: tests/model/check.sh [WORK_DIR]   (default: a temporary directory)
# Needs spin (Debian package "spin") and gcc. Exit status 0 only if all hold.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
work=${1:-$(mktemp -d)}
mkdir -p "$work"
for tool in spin gcc; do
  command -v "$tool" >/dev/null || { echo "check.sh: $tool is not installed (.ci/install-deps)"; exit 1; }
done

# StageOptions the model distinguishes: list_buffers, blending.
configs=("" "-DBUFFERS=2" "-DBLEND" "-DBLEND -DBUFFERS=2" "-DBLEND -DBUFFERS=4")
properties=(shutdown_completes cancel_returns)
# The largest state space: safety only, to keep the check short on a busy
# machine.
safety_only="-DBLEND -DBUFFERS=4"
# -DCOLLAPSE keeps the largest configuration near 150 MB; -m is the depth
# bound, and a search that hits it fails below (it would be incomplete).
cflags=(-O2 -w -DCOLLAPSE)
depth=2000000

# pan MODEL SPIN_FLAGS NAME [-DNOCLAIM | -N CLAIM]: builds and runs one search
# in its own directory; its report is in $work/NAME/report.
pan() {
  local model=$1 flags=$2 name=$3 mode=$4 claim=${5:-}
  local dir="$work/$name"
  rm -rf "$dir" && mkdir -p "$dir"
  (
    cd "$dir"
    # shellcheck disable=SC2086 # FLAGS is a list of -D options
    spin $flags -a "$here/$model" >spin.log 2>&1 || { cat spin.log; exit 1; }
    if [ "$mode" = safety ]; then
      gcc "${cflags[@]}" -DNOCLAIM -o pan pan.c
      ./pan -m"$depth" >report 2>&1 || true
    else
      gcc "${cflags[@]}" -o pan pan.c
      ./pan -m"$depth" -a -f -N "$claim" >report 2>&1 || true
    fi
  )
}

errors_of() { sed -n 's/.*errors: \([0-9]*\).*/\1/p' "$1"; }
states_of() { sed -n 's/^ *\([0-9.e+]*\) states, stored.*/\1/p' "$1"; }

status=0
bad() { echo "FAIL $*"; status=1; }

run=0
for cfg in "${configs[@]}"; do
  run=$((run + 1))
  label="exchange.pml ${cfg:-(defaults)}"
  pan exchange.pml "$cfg" "good$run" safety
  r="$work/good$run/report"
  if grep -q "max search depth too small" "$r"; then bad "$label: search truncated at depth $depth"; continue; fi
  [ "$(errors_of "$r")" = 0 ] || { bad "$label: safety"; sed -n '1,5p' "$r"; continue; }
  # Vacuity: a statement that is never reached is a property never tested.
  unreached=$(awk '/^unreached in proctype/ {p=1; next} p && /of [0-9]+ states\)/ {gsub(/[()]/,""); n+=$1; p=0} END {print n+0}' "$r")
  [ "$unreached" = 0 ] || { bad "$label: $unreached unreached statements"; grep -A8 "^unreached in proctype" "$r"; continue; }
  echo "ok   $label: safety, 0 errors, $(states_of "$r") states, every statement reached"
  [ "$cfg" = "$safety_only" ] && continue
  for p in "${properties[@]}"; do
    pan exchange.pml "$cfg" "good$run-$p" ltl "$p"
    r="$work/good$run-$p/report"
    if grep -q "max search depth too small" "$r"; then bad "$label: ltl $p truncated"; continue; fi
    if [ "$(errors_of "$r")" = 0 ]; then
      echo "ok   $label: ltl $p (weak fairness), 0 errors, $(states_of "$r") states"
    else
      bad "$label: ltl $p"
      sed -n '1,5p' "$r"
    fi
  done
done

found=0
for model in "$here"/exchange_broken_*.pml; do
  found=$((found + 1))
  name=$(basename "$model" .pml)
  flags=$(sed -n 's/.*spin-flags:\(.*\)$/\1/p' "$model" | head -n1)
  pan "$(basename "$model")" "$flags" "$name" safety
  r="$work/$name/report"
  n=$(errors_of "$r")
  if [ -n "$n" ] && [ "$n" -gt 0 ]; then
    why=$(grep -m1 -E "assertion violated|invalid end state|acceptance cycle" "$r" | sed 's/^pan:[0-9]*: *//')
    echo "ok   $name${flags:+ [$flags ]}: rejected: $why"
  else
    bad "$name${flags:+ [$flags ]}: spin found no error, the check does not bite"
    sed -n '1,12p' "$r"
  fi
done
((found > 0)) || bad "no exchange_broken_*.pml model"

((status == 0)) && echo "exchange model: all checks passed (reports in $work)"
exit "$status"
