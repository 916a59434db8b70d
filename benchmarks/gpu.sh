#!/bin/bash
# The GPU benchmark session (cuda_ad_mono) for docs/performance.md, in order of priority, within
# BUDGET seconds in all (a lent GPU has minutes): the authors' table (benchmarks.authors; the
# certificates, which run on the CPU and are not in the table, off), the letters' seeds, then
# benchmarks.run, .scaling, .objectives and .speed while time is left. Each step gets what is
# left of the budget; a stopped step keeps the rows it wrote.
# Needs Mitsuba, Dr.Jit, trimesh, manifold3d, nlopt and shapely importable (on the offline device
# machine: PYTHONPATH from ../shared/tools/gpu-site.sh's .gpu/site.tar.xz, packed with
# `PYTHON=.venv/bin/python ../shared/tools/gpu-site.sh shapely svg.path`; coal and OMPL, which the
# thin-plate step needs, from tools/gpu_extra.sh's .gpu/extra.tar.xz, unpacked beside it with
# /tmp/site/cmeel.prefix/lib/python3.12/site-packages on PYTHONPATH too). Writes into
# ${OUT:-benchmarks/results}.
#   usage: [TAG=h200] [BUDGET=540] [CASES=a,b,...] benchmarks/gpu.sh [letters-seeds...]
set -u
out=${OUT:-benchmarks/results}
mkdir -p "$out"
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
export PYTHONUNBUFFERED=1 SIEVE_MI_VARIANT=cuda_ad_mono
deadline=$(($(date +%s) + ${BUDGET:-540}))
left() { echo $((deadline - $(date +%s))); }
step() {  # step NAME CMD...: run CMD with what is left of the budget
  local name=$1 t
  shift
  t=$(left)
  if [ "$t" -lt 20 ]; then echo "== $name: skipped (budget spent)"; return; fi
  echo "== $name ($(date -u +%H:%M:%S), ${t} s left)"
  timeout -k 5 "$t" "$@"
  echo "== $name: exit $? ($(date -u +%H:%M:%S))"
}
nvidia-smi -L 2>/dev/null
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader 2>/dev/null
step smoke python3 -c "import mitsuba as mi, drjit as dr; mi.set_variant('cuda_ad_mono'); \
print('mitsuba', mi.__version__, 'drjit', dr.__version__, mi.variant())" || exit 1
cases=${CASES:-arch-vs-rect-prism,bowtie-vs-sphere,fig2-beetle-vs-beetle-front,fandisk-cut-vs-fandisk,bunny-multi-b,mechanical-parts,bunny-poses-multi-b,three-a-three-b,random-10}
step authors python3 -m benchmarks.authors --variant cuda_ad_mono --out "$out" --timeout 150 \
  --set verdict.certify=false --only "$cases"
# The letters without their certificates (300 s per B on the CPU; the timings are search + verdict).
sed 's/^certify_budget = .*/certify = false/' scenes/letters.toml > scenes/.letters-gpu.toml
trap 'rm -rf "$scratch" scenes/.letters-gpu.toml' EXIT
for seed in "${@:-0}"; do
  step "letters seed $seed" bash -c "python3 -m sieve_mi solve scenes/.letters-gpu.toml --seed $seed \
    --out $scratch/letters_$seed --quiet --json --no-figure --no-animation > $out/letters_$seed.json"
  python3 -c "import json; r = json.load(open('$out/letters_$seed.json')); t = r['timings']; \
print('letters seed $seed: search', round(t['search_s'], 1), 'verdict', round(t['verdict_s'], 1), \
'winner', r['winner'])" 2>/dev/null
done
step run python3 -m benchmarks.run --variant cuda_ad_mono --out "$out" --tag "${TAG:-gpu}"
step scaling python3 -m benchmarks.scaling --variant cuda_ad_mono --out "$out/scaling_b_cuda.png"
for k in 10 100; do step "objectives $k" python3 -m benchmarks.objectives --variant cuda_ad_mono --poses $k; done
step speed python3 -m benchmarks.speed --variant cuda_ad_mono --repeat 2
