#!/usr/bin/env sh
# Installs what bake needs at run time on Debian/Ubuntu: the Vulkan loader and
# Mesa's drivers, whose lavapipe runs wgpu on the CPU when there is no GPU;
# and make, which runs the build-step example (pipeline/Makefile) and its test.
# Does nothing when they are already installed.
set -eu
packages="mesa-vulkan-drivers libvulkan1 make"
missing=""
for p in $packages; do
    dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"
done
[ -z "$missing" ] && exit 0
if [ "$(id -u)" -eq 0 ]; then sudo=""; else sudo="sudo"; fi
echo "installing:$missing" >&2
$sudo apt-get update -q
$sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -q $missing
