#!/usr/bin/env bash
# Seeds for fuzz_scene: every shipped scene, its parameter_set pointed at params.yaml and
# followed by the parameter set it names; then every parameter set under reference-data/
# behind a minimal scene naming it.
#   bash fuzz/make_seeds.sh OUTDIR
set -euo pipefail
cd "$(dirname "$0")/.."
out="$1"
mkdir -p "$out"
for f in reference-data/scenes/*.yaml reference-data/scenes/*/*.yaml; do
  grep -q '^parameter_set:' "$f" || continue
  ps=$(sed -n 's/^parameter_set: *//p' "$f")
  ps_file="$(dirname "$f")/$ps"
  [[ -f "$ps_file" ]] || ps_file="reference-data/$ps"
  { sed 's|^parameter_set: .*|parameter_set: params.yaml|' "$f"; printf '\n#@params\n'; cat "$ps_file"; } \
      > "$out/$(basename "$(dirname "$f")")_$(basename "$f")"
done
for ps_file in reference-data/*.yaml; do
  { printf 'name: seed\nparameter_set: params.yaml\nligaments: all\ncontacts: [medial, lateral]\ngravity: {enabled: true}\npulse: {shape: none}\n'
    printf 'initial_state: {pose: reference}\nend: {time_s: 0.01}\n\n#@params\n'; cat "$ps_file"; } \
      > "$out/parameter_set_$(basename "$ps_file")"
done
# Inputs that once crashed the target (fixed since) run first in every campaign:
#   field_keys_stack_use_after_scope.bin — Field::Keys held a reference into a temporary
#   yaml-cpp iterator value (ASan stack-use-after-scope).
cp fuzz/regressions/* "$out/"
