#!/usr/bin/env bash
# Installs the Debian 12 packages occmap needs, only those that are missing.
# Uses sudo when not root. Safe to run repeatedly: a no-op once everything is there.
set -euo pipefail
packages=(
  build-essential cmake ninja-build pkg-config ccache python3
  libopencv-dev
  libavcodec-dev libavformat-dev libavutil-dev libswscale-dev libavdevice-dev
  libeigen3-dev libyaml-cpp-dev nlohmann-json3-dev libcli11-dev
  libfmt-dev libspdlog-dev libtbb-dev libhwy-dev
  googletest libgtest-dev libgmock-dev libbenchmark-dev
  libmosquitto-dev mosquitto mosquitto-clients
  libcpp-httplib-dev curl
  ffmpeg
  chromium-headless-shell
  pybind11-dev python3-dev python3-numpy python3-pytest
  dpkg-dev file
)
missing=()
for p in "${packages[@]}"; do
  status=$(dpkg-query -W -f='${db:Status-Status}' "$p" 2>/dev/null || true)
  [ "$status" = "installed" ] || missing+=("$p")
done
# The web front end is bundled with npm (Debian 12: nodejs 18 and npm 9); a Node.js from elsewhere
# (NodeSource's nodejs ships its own npm and conflicts with Debian's) is as good.
if ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; then
  missing+=(nodejs npm)
fi
if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi
echo "occmap: installing missing Debian packages: ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1; then SUDO="sudo"; else
    echo "occmap: not root and no sudo; install these packages by hand: ${missing[*]}" >&2
    exit 1
  fi
fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
