#!/usr/bin/env bash
# Seeds for fuzz_scene: every shipped scene, its parameter_set pointed at params.yaml and
# followed by the parameter set it names (the chapter's or the exact one).
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
# Inputs that once crashed the target (fixed since) run first in every campaign:
#   field_keys_stack_use_after_scope.bin — Field::Keys held a reference into a temporary
#   yaml-cpp iterator value (ASan stack-use-after-scope), issue 18.
cp fuzz/regressions/* "$out/"
