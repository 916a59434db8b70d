#!/bin/bash
# The GPU benchmark session (cuda_ad_mono), as run on a lent H100 for docs/performance.md.
# Needs Mitsuba, Dr.Jit, trimesh, manifold3d and nlopt importable (on the offline device machine:
# PYTHONPATH from ../shared/tools/gpu-site.sh's .gpu/site.tar.xz). Writes into ${OUT:-benchmarks/results}.
#   usage: [TAG=h100] benchmarks/gpu.sh [letters-seeds...]
set -u
out=${OUT:-benchmarks/results}
mkdir -p "$out"
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
export PYTHONUNBUFFERED=1 SIEVE_MI_VARIANT=cuda_ad_mono
nvidia-smi -L 2>/dev/null
for seed in "${@:-0}"; do
  echo "== letters seed $seed"
  python3 -m sieve_mi solve scenes/letters.toml --seed "$seed" --out "$scratch/letters_$seed" --quiet --no-figure 2>&1 | grep -E "letter_|winner"
done
python3 -m benchmarks.run --variant cuda_ad_mono --out "$out" --tag "${TAG:-gpu}" 2>&1 | grep -v '^|'
python3 -m benchmarks.scaling --variant cuda_ad_mono --out "$out/scaling_b_cuda.png"
for k in 10 100; do python3 -m benchmarks.objectives --variant cuda_ad_mono --poses $k; done
python3 -m benchmarks.speed --variant cuda_ad_mono --repeat 2   # frozen vs traced; clearance vs overlap
