#!/usr/bin/env bash
# Makes sure a libLLVM that Dr.Jit 1.5 accepts (version >= 17) is on this machine.
# Dr.Jit's LLVM backend dies on libLLVM 14-16 ("Cannot select: ... fminimum"); Debian's libllvm19 works.
set -euo pipefail
found=""
for f in /usr/lib/llvm-{25,24,23,22,21,20,19,18,17}/lib/libLLVM*.so* /usr/lib/*-linux-gnu/libLLVM-{25,24,23,22,21,20,19,18,17}.so* \
         /usr/lib/*-linux-gnu/libLLVM.so.{25,24,23,22,21,20,19,18,17}* /opt/homebrew/opt/llvm/lib/libLLVM.dylib /usr/local/opt/llvm/lib/libLLVM.dylib; do
  if [ -e "$f" ]; then found="$f"; break; fi
done
if [ -n "${DRJIT_LIBLLVM_PATH:-}" ] && [ -e "$DRJIT_LIBLLVM_PATH" ]; then found="$DRJIT_LIBLLVM_PATH"; fi
if [ -n "$found" ]; then echo "libLLVM for Dr.Jit: $found"; exit 0; fi
if command -v apt-get >/dev/null 2>&1; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  echo "installing Debian's libllvm19 (Dr.Jit's LLVM backend needs libLLVM >= 17)"
  $SUDO apt-get install -y -q libllvm19 >/dev/null 2>&1 || { $SUDO apt-get update -q >/dev/null && $SUDO apt-get install -y -q libllvm19 >/dev/null; }
  exit 0
fi
echo "error: no libLLVM >= 17 found; install LLVM 17 or newer (e.g. 'apt-get install libllvm19') or set DRJIT_LIBLLVM_PATH" >&2
exit 1
