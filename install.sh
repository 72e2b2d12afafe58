#!/usr/bin/env bash
# Install everything the project needs on a fresh machine (Debian + Python >= 3.11 + Node):
# system libraries for headless rendering, espeak-ng, Chromium (the annotation page's browser
# tests), the Node tools (the Khronos glTF validator used by the tests; three.js, bundled
# into the annotation page), the Python package with its test extras, and mediapipe (the
# face mesh behind the automatic feature points).
set -euo pipefail
cd "$(dirname "$0")"

need=()
for pkg in libegl1 libgl1-mesa-dri libgbm1 espeak-ng chromium chromium-driver; do
  dpkg -s "$pkg" >/dev/null 2>&1 || need+=("$pkg")
done
if [ ${#need[@]} -gt 0 ]; then
  if [ "$(id -u)" = 0 ]; then
    echo "install.sh: installing Debian packages: ${need[*]}"
    apt-get update -qq && apt-get install -y -qq "${need[@]}" >/dev/null
  else
    echo "install.sh: please install the Debian packages ${need[*]} (sudo apt-get install ${need[*]})" >&2
    exit 1
  fi
fi

npm ci --silent --no-audit --no-fund
npm run build --silent  # three.js for the annotation page's 3D view, before the package is installed
python3 -m pip install -q --disable-pip-version-check -e ".[test,landmarks,bench]"
# The face models for automatic feature points (recon.landmarks) are inside the mediapipe
# wheel; installed without its declared dependencies (see pyproject.toml's landmarks extra).
python3 -m pip install -q --disable-pip-version-check --no-deps "mediapipe==0.10.21"
echo "install.sh: done"
