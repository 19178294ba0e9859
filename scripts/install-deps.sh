#!/usr/bin/env bash
# Installs the Debian 12 packages the project needs, only those missing.
# Idempotent; safe to run on every ./bms call (a no-op when all are present).
set -euo pipefail
groups="${1:-host}"
pkgs=(cmake ninja-build g++ pkg-config libeigen3-dev libsundials-dev libsuitesparse-dev
      nlohmann-json3-dev libcli11-dev libfmt-dev libgtest-dev libgmock-dev libbenchmark-dev
      gnuplot-nox python3-matplotlib python3-numpy)
case " $groups " in *" cross "*|*" all "*)
  pkgs+=(gcc-arm-none-eabi libnewlib-arm-none-eabi libstdc++-arm-none-eabi-newlib qemu-system-arm python3) ;; esac
case " $groups " in *" can "*|*" all "*)
  pkgs+=(user-mode-linux kmod iproute2 can-utils python3-can python3-canmatrix gcc) ;; esac
# Fallback backend of scripts/vcan-run.sh where User-Mode Linux does not boot (large).
case " $groups " in *" can-qemu "*|*" all "*)
  pkgs+=(qemu-system-x86 linux-image-amd64 busybox-static cpio kmod iproute2 can-utils python3-can) ;; esac
case " $groups " in *" analysis "*|*" all "*)
  pkgs+=(clang clang-tidy cppcheck libclang-rt-14-dev) ;; esac
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
echo "bms: installing ${missing[*]}" >&2
SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
stamp=/var/lib/apt/periodic/bms-update-stamp
if [ ! -f "$stamp" ] || [ -z "$(find "$stamp" -mmin -720 2>/dev/null)" ]; then
  $SUDO apt-get update -qq && { $SUDO mkdir -p "$(dirname "$stamp")"; $SUDO touch "$stamp"; }
fi
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
# The downloaded .deb files are not needed once installed; on a small disk they are what
# the builds and tests run out of (gcc-arm-none-eabi alone is hundreds of MB).
$SUDO apt-get clean
