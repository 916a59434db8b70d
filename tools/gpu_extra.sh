#!/usr/bin/env bash
# Packs what ../shared/tools/gpu-site.sh leaves out, for an offline GPU machine (x86-64, Python
# 3.12): coal (with only the shared libraries it loads: boost, assimp, octomap, qhull, eigenpy),
# OMPL, lxml and pytest-xdist, into .gpu/extra.tar.xz (about 16 MB; with site.tar.xz and the
# working tree it fits the device's 64 MiB carry). MuJoCo and CoACD (shake) do not fit as well:
# the shake tests fail there for want of them. On that machine:
#   mkdir -p /tmp/site && tar xJf .gpu/site.tar.xz -C /tmp/site && tar xJf .gpu/extra.tar.xz -C /tmp/site &&
#   export PYTHONPATH=/tmp/site:/tmp/site/cmeel.prefix/lib/python3.12/site-packages:$PWD
# (PYTHONPATH skips .pth files, so cmeel's site-packages is named). Usage: tools/gpu_extra.sh
set -euo pipefail
root=$(git rev-parse --show-toplevel)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
  --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 --platform manylinux_2_17_x86_64 \
  --platform manylinux2014_x86_64 -d "$tmp/whl" coal==3.0.3 libcoal==3.0.3 eigenpy==3.13.0 \
  cmeel-boost==1.90.0 cmeel-assimp==6.0.5 cmeel-octomap==1.10.0 cmeel-qhull==8.0.2.1 ompl==2.0.1 \
  lxml pytest-xdist execnet
mkdir -p "$tmp/site"
for w in "$tmp"/whl/*.whl; do (cd "$tmp/site" && python3 -m zipfile -e "$w" .); done
cd "$tmp/site/cmeel.prefix"
rm -rf include share bin lib/cmake lib/pkgconfig lib64
keep="libassimp libboost_atomic libboost_container libboost_filesystem libboost_graph libboost_python312
  libboost_serialization libcoal libeigenpy liboctomap liboctomath libqhull_r"
for f in lib/*; do
  [ -d "$f" ] && continue
  name=$(basename "$f") wanted=0
  for k in $keep; do case $name in "$k".so*) wanted=1 ;; esac; done
  soname=$(readelf -d "$f" 2>/dev/null | sed -n 's/.*SONAME.*\[\(.*\)\]/\1/p')
  # zip extraction turns symlinks into copies: keep one file per library, under its SONAME
  if [ $wanted = 0 ] || { [ -n "$soname" ] && [ "$name" != "$soname" ]; }; then rm -f "$f"; fi
done
cd "$tmp/site"
rm -f ./*.dist-info/RECORD
mkdir -p "$root/.gpu"
tar cf - . | xz -T2 -6 > "$root/.gpu/extra.tar.xz"
ls -la "$root/.gpu/extra.tar.xz"
