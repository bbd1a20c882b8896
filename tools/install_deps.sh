#!/usr/bin/env bash
# Installs every build and test dependency of clutterseg from Debian 12 packages.
# Usage: tools/install_deps.sh [--pcl]   (--pcl adds libpcl-dev for the optional baseline)
set -euo pipefail
if [ "$(id -u)" -ne 0 ]; then SUDO=sudo; else SUDO=; fi
pkgs=(
  build-essential cmake ninja-build pkg-config git python3
  libeigen3-dev libnanoflann-dev
  libopenni2-0 libopenni2-dev openni2-utils
  liblcm1 liblcm-dev liblcm-bin liblcm-java default-jdk-headless
  libgtest-dev libgmock-dev libbenchmark-dev
  libpng-dev libdeflate-dev zlib1g-dev libyaml-cpp-dev libcli11-dev libsystemd-dev nlohmann-json3-dev
  libjchart2d-java dpkg-dev file
  clang libclang-rt-14-dev clang-format iproute2
  python3-dev pybind11-dev python3-numpy python3-pytest
)
if [ "${1:-}" = "--pcl" ]; then pkgs+=(libpcl-dev); fi
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ "${#missing[@]}" -gt 0 ]; then
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get -o DPkg::Lock::Timeout=900 update -qq
  $SUDO apt-get -o DPkg::Lock::Timeout=900 install -y -qq --no-install-recommends "${missing[@]}"
fi
