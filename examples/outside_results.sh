#!/bin/sh
# The outside solvers of examples/ on the chapter scene, each scored by `kneedyn score`
# (docs/problem.md), for `work_precision --include OUT_DIR` and `report.py --include OUT_DIR`:
#   SciPy's solve_ivp (Radau, BDF, LSODA, DOP853) at rtol 1e-4, 1e-6, 1e-8, 1e-10 (atol 1e-2 rtol,
#   as the sweep's adaptive settings), through kneedyn.Problem;
#   the C program (examples/c, RK4) at h = 1e-3, 2.5e-4, 6.25e-5 s, through kneedyn/problem.h.
# A run that fails is scored as failed (--failed) and stays a result; this script then goes on.
#
#   examples/outside_results.sh KNEEDYN RK4_ON_THE_KNEE PYTHONPATH OUT_DIR
# PYTHONPATH: the directory holding the kneedyn package (build/python); empty: SciPy is left out.
set -eu
if [ $# -ne 4 ]; then
  echo "usage: $0 KNEEDYN RK4_ON_THE_KNEE PYTHONPATH OUT_DIR" >&2
  exit 2
fi
kneedyn=$1 rk4=$2 pypath=$3 out=$4
here=$(cd "$(dirname "$0")" && pwd)
scene="$here/../reference-data/scenes/chapter_impact.yaml"
mkdir -p "$out"
if [ -n "$pypath" ]; then
  for method in Radau BDF LSODA DOP853; do
    for rtol in 1e-4 1e-6 1e-8 1e-10; do
      atol=$(/usr/bin/python3 -c "print(1e-2 * $rtol)")
      # Exit 1: the run failed and was scored as failed.
      PYTHONPATH="$pypath" /usr/bin/python3 "$here/python/scipy_on_the_knee.py" --scene "$scene" --method "$method" \
          --rtol "$rtol" --atol "$atol" --out "$out/scipy_${method}_rtol$rtol" --kneedyn "$kneedyn" > /dev/null || true
      [ -f "$out/scipy_${method}_rtol$rtol/score.json" ] || { echo "$0: scipy $method $rtol wrote no score" >&2; exit 1; }
    done
  done
fi
for step in 1e-3 2.5e-4 6.25e-5; do
  dir="$out/c_rk4_h$step"
  mkdir -p "$dir"
  failed=""
  "$rk4" "$scene" "$step" "$dir" > "$dir/log.txt" 2>&1 || failed="rk4_on_the_knee: $(tail -n 1 "$dir/log.txt")"
  cpu=$(cat "$dir/cpu_time_s" 2>/dev/null || echo -1)
  set -- --scene "$scene" --events "$dir/events.csv" --solver-name c-example --integrator rk4 --step "$step" \
      --out "$dir/score.json"
  [ -f "$dir/counters.json" ] && set -- "$@" --counters "$dir/counters.json"
  if [ -n "$failed" ]; then
    "$kneedyn" score "$dir/trajectory.csv" "$@" --failed "$failed" > /dev/null
  else
    "$kneedyn" score "$dir/trajectory.csv" "$@" --cpu-time "$cpu" > /dev/null
  fi
done
echo "outside_results: $(find "$out" -name score.json | wc -l) scored results in $out"
