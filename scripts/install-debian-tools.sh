#!/bin/sh
# The Debian packages frogsim's firmware path needs (the AVR tool chain, the Arduino AVR core and
# its makefile, simavr) and MuJoCo's offscreen drawing (EGL through Mesa: the animations and the
# environments' rgb_array rendering, tested with MUJOCO_GL=egl): installed if missing, so the
# README's commands work on a fresh machine. Quiet and quick when everything is already there.
set -eu
packages="gcc-avr avr-libc binutils-avr arduino-core-avr arduino-mk simavr libsimavr-dev
          libegl1 libegl-mesa0 libgl1-mesa-dri libgbm1"
missing=""
for p in $packages; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing="$missing $p"
done
[ -z "$missing" ] && exit 0
echo "installing Debian packages:$missing" >&2
if [ "$(id -u)" -ne 0 ]; then
    echo "frogsim: not root: run 'sudo apt-get update && sudo apt-get install -y$missing'" >&2
    exit 1
fi
export DEBIAN_FRONTEND=noninteractive
apt-get update -q >/dev/null
apt-get install -y -q $missing >/dev/null
