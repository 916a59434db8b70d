#!/usr/bin/env bash
# Best effort: installs Debian's headless Chromium for the browser tests of report.html
# (tests/outputs/test_viewer.py skips them where no browser is found). Never fails the set-up.
set -u
for b in chromium chromium-browser google-chrome google-chrome-stable; do
  if command -v "$b" >/dev/null 2>&1; then echo "browser for the page tests: $(command -v "$b")"; exit 0; fi
done
if command -v apt-get >/dev/null 2>&1; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  if [ -n "$SUDO" ] && ! sudo -n true 2>/dev/null; then
    echo "note: no chromium and no root; the browser tests of report.html will be skipped"; exit 0
  fi
  echo "installing Debian's chromium (headless browser tests of report.html)"
  $SUDO apt-get install -y -q chromium >/dev/null 2>&1 \
    || { $SUDO apt-get update -q >/dev/null 2>&1 && $SUDO apt-get install -y -q chromium >/dev/null 2>&1; } \
    || echo "note: could not install chromium; the browser tests of report.html will be skipped"
  exit 0
fi
echo "note: no chromium and no apt-get; the browser tests of report.html will be skipped"
exit 0
