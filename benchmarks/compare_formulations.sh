#!/usr/bin/env bash
# Every formulation on the chapter scene against dae at rtol 1e-10 (the reference here):
# event times and angles, the state at 90 deg, statistics, drift, wall time. Markdown on stdout.
#   benchmarks/compare_formulations.sh [KNEEDYN_BINARY] [OUT_DIR]
set -u
cd "$(dirname "$0")/.."
K=${1:-build/formulations/kneedyn}
S=reference-data/scenes/chapter_impact.yaml
O=${2:-out/compare_formulations}; rm -rf "$O"; mkdir -p "$O"
run() { name=$1; shift; "$K" run "$S" --out "$O/$name" --quiet "$@" > "$O/$name.log" 2>&1; echo "$name|$*" >> "$O/index"; }
run dae_ref --formulation dae --rtol 1e-10 --atol 1e-12
run dae-reduced --formulation dae-reduced --rtol 1e-10 --atol 1e-12
run mde_dopri5 --formulation mde --integrator dopri5 --rtol 1e-10 --atol 1e-12
run mde_fehlberg78 --formulation mde --integrator fehlberg78 --rtol 1e-10 --atol 1e-12
run mde_cvode-bdf --formulation mde --integrator cvode-bdf --rtol 1e-10 --atol 1e-12
run mde_rk4 --formulation mde --integrator rk4 --step 1e-4
run mde_euler --formulation mde --integrator euler --step 1e-5
run ede_none --formulation ede --integrator dopri5 --rtol 1e-10 --atol 1e-12
run ede_baumgarte --formulation ede --integrator dopri5 --stabilization baumgarte --rtol 1e-10 --atol 1e-12
run ede_projection --formulation ede --integrator dopri5 --stabilization projection --rtol 1e-10 --atol 1e-12
run ede_rk4_none --formulation ede --integrator rk4 --step 1e-3
run ede_rk4_projection --formulation ede --integrator rk4 --step 1e-3 --stabilization projection
run newmark --formulation newmark --step 1e-4 --rtol 1e-10 --atol 1e-12
run newmark-reduced --formulation newmark-reduced --step 1e-4 --rtol 1e-10 --atol 1e-12
run dae-ggl --formulation dae-ggl --rtol 1e-10 --atol 1e-12
run dae-ggl-reduced --formulation dae-ggl-reduced --rtol 1e-10 --atol 1e-12
run generalized-alpha --formulation generalized-alpha --step 1e-4 --rtol 1e-10 --atol 1e-12
run generalized-alpha-reduced --formulation generalized-alpha-reduced --step 1e-4 --rtol 1e-10 --atol 1e-12
run ede_cvode-bdf_cvode-projection --formulation ede --integrator cvode-bdf --stabilization cvode-projection --rtol 1e-10 --atol 1e-12
# A formulation registered since this list was written runs too, with its own defaults at
# rtol 1e-10 (`kneedyn formulations` lists them; those that need a patella are left out).
listed=$(cut -d'|' -f2 "$O/index" | grep -o -- '--formulation [^ ]*' | cut -d' ' -f2 | sort -u)
for f in $("$K" formulations | grep -v '\[needs a patella' | cut -d' ' -f1); do
  grep -qxF -- "$f" <<< "$listed" || run "$f" --formulation "$f" --rtol 1e-10 --atol 1e-12
done
/usr/bin/python3 - "$O" <<'PY'
import json, sys, os
O = sys.argv[1]
ref = json.load(open(f"{O}/dae_ref/summary.json"))
def ev(s, n):
    e = [x for x in s.get("events", []) if x["name"] == n]
    return e[-1] if e else None
rf = ref["final_state"]
print("| formulation (setting) | status | lift-off lateral t (s), angle (°) | Δt lift-off (s) | Δ angle (°) | Δt 90° (s) | max abs ΔR0 at 90° (mm) | max abs Δangle at 90° (°) | ΔN_medial at 90° (N) | steps | RHS/res evals | Jac | LU | Newton | max gap (mm) | wall (s) |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
for line in open(f"{O}/index"):
    name, args = line.strip().split("|", 1)
    p = f"{O}/{name}/summary.json"
    if not os.path.exists(p):
        print(f"| {name} `{args}` | no output | | | | | | | | | | | | | | | |"); continue
    s = json.load(open(p)); st = s["statistics"]; f = s.get("final_state", {})
    lo = ev(s, "liftoff_lateral"); f9 = ev(s, "flexion_90"); rlo = ev(ref, "liftoff_lateral"); r9 = ev(ref, "flexion_90")
    nlo = sum(1 for x in s["events"] if x["name"].startswith("liftoff"))
    dR = max(abs(a - b) for a, b in zip(f["R0_mm"], rf["R0_mm"])) if f else float("nan")
    dA = max(abs(f[k] - rf[k]) for k in ("flexion_deg", "valgus_deg", "external_rotation_deg")) if f else float("nan")
    dN = abs(f["contacts"]["medial"]["normal_force_N"] - rf["contacts"]["medial"]["normal_force_N"]) if f else float("nan")
    status = s["status"] + ("" if nlo <= 1 else f" ({nlo} lift-offs)")
    print(f"| {name} `{args}` | {status} | {lo['time']:.6f}, {lo['flexion_deg']:.4f} | {lo['time']-rlo['time']:+.1e} | {lo['flexion_deg']-rlo['flexion_deg']:+.1e} | "
          + (f"{f9['time']-r9['time']:+.1e}" if f9 else "—") + f" | {dR:.1e} | {dA:.1e} | {dN:.1e} | {st['steps']} | {st['residual_evaluations']} | {st['jacobian_evaluations']} | {st['linear_solver_setups']} | {st['nonlinear_iterations']} | {s['constraint_residuals']['max_gap_mm']:.1e} | {s['wall_time_s']:.3f} |")
PY
