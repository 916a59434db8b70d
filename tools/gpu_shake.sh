#!/usr/bin/env bash
# Packs what `sieve-mi shake` needs on a lent device machine (x86-64, Python 3.12, numpy and scipy
# present, no internet) without Mitsuba: MuJoCo (its core library only, not the studio), CoACD,
# trimesh, shapely, manifold3d, nlopt and svg.path, into .gpu/shake.tar.xz (about 12 MB). Trials
# are CPU work: this pack lets a batch of them use the device host's cores. On that machine:
#   mkdir -p /tmp/site && tar xJf .gpu/shake.tar.xz -C /tmp/site && export PYTHONPATH=/tmp/site:$PWD
# then `python3 -m sieve_mi shake DIR --workers N ...`. Usage: [PYTHON=.venv/bin/python] tools/gpu_shake.sh
set -euo pipefail
root=$(git rev-parse --show-toplevel)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
ver() { "${PYTHON:-$root/.venv/bin/python}" -c "import importlib.metadata as m; print(m.version('$1'))"; }
spec=()
for p in mujoco mujoco-core coacd trimesh shapely manifold3d nlopt svg.path; do spec+=("$p==$(ver "$p")"); done
python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
  --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 --platform manylinux_2_17_x86_64 \
  --platform manylinux2014_x86_64 -d "$tmp/whl" "${spec[@]}"
mkdir -p "$tmp/site"
for w in "$tmp"/whl/*.whl; do (cd "$tmp/site" && python3 -m zipfile -e "$w" .); done
cd "$tmp/site"
# The engine only: no viewer, no docs, no headers, no tests.
rm -rf mujoco/studio mujoco/doc mujoco/include mujoco/*_test.py mujoco/mjx ./*.dist-info/RECORD
mkdir -p "$root/.gpu"
tar cf - . | xz -T2 -6 > "$root/.gpu/shake.tar.xz"
ls -la "$root/.gpu/shake.tar.xz"
