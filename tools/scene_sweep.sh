#!/usr/bin/env bash
# Solve every scene in scenes/ with its default seed and keep each report.json in DEST
# (used to check that a refactor keeps winners, betas and protrusions: tools/compare_reports.py).
set -euo pipefail
dest=${1:?usage: tools/scene_sweep.sh DEST [scene.toml ...]}
shift
mkdir -p "$dest"
scenes=("$@")
[ ${#scenes[@]} -gt 0 ] || scenes=(scenes/*.toml)
for s in "${scenes[@]}"; do
  grep -q '^\[\[shape\]\]' "$s" && continue  # a mixture for sieve-mi sort, not a scene
  name=$(basename "$s" .toml)
  tmp=$(mktemp -d)
  .venv/bin/python -m sieve_mi solve "$s" --out "$tmp/o" --quiet --no-figure > "$dest/$name.txt" 2>&1 || echo "failed: $s" >> "$dest/$name.txt"
  cp "$tmp/o/report.json" "$dest/$name.json" 2>/dev/null || true
  rm -rf "$tmp"
  echo "$name done"
done
