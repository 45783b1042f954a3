#!/usr/bin/env bash
# Installs every Debian package noisemon needs to build, run and test. Idempotent; run as root (or via sudo).
set -euo pipefail
packages=(
  build-essential cmake pkg-config ninja-build
  libeigen3-dev libspdlog-dev libfmt-dev libtomlplusplus-dev libcli11-dev
  liblcm-dev liblcm-bin liblcm-java libglib2.0-dev default-jdk-headless
  libcomedi-dev libasound2-dev libsystemd-dev libsndfile1-dev nlohmann-json3-dev libceres-dev libhdf5-dev
  clang libclang-rt-14-dev clang-tidy clang-format
  libgtest-dev libgmock-dev libbenchmark-dev libfftw3-dev
  iproute2 util-linux python3 python3-canmatrix python3-h5py python3-numpy python3-scipy systemd
  libcpp-httplib-dev chromium libjchart2d-java
)
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ "${#missing[@]}" -gt 0 ]; then
  echo "noisemon: installing ${missing[*]}" >&2
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update
  $SUDO apt-get install -y --no-install-recommends "${packages[@]}"
fi
