#!/usr/bin/env bash
# Installs the Debian packages multiform needs, if they are missing:
#   graphviz (net diagrams), ffmpeg (MP4 videos), chromium (report page test),
#   libegl1 + libegl-mesa0 + libosmesa6 (MuJoCo's offscreen renderer without a GPU).
set -euo pipefail
pkgs=(graphviz ffmpeg chromium libegl1 libegl-mesa0 libosmesa6)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi
echo "installing system packages: ${missing[*]}"
if ! command -v apt-get >/dev/null; then
  echo "error: apt-get not found; install these packages yourself: ${missing[*]}" >&2
  exit 1
fi
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
