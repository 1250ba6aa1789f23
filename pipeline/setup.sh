#!/usr/bin/env sh
# Installs what bake and its tests need on Debian/Ubuntu, doing nothing that is
# already done:
# - the Vulkan loader and Mesa's drivers, whose lavapipe runs wgpu on the CPU
#   when there is no GPU;
# - make, which runs the build-step example (pipeline/Makefile) and its test;
# - Node.js (when there is no `node`), the Khronos glTF validator, gltfpack,
#   glTF-Transform with Google's Draco library and Binomial's Basis Universal
#   encoder (ktx2-encoder), from npm at the versions pinned in
#   pipeline/package-lock.json, into pipeline/node_modules (ignored by git);
#   tests/it/validator.rs runs the validator through pipeline/validate.mjs,
#   tests/it/gltfpack.rs runs gltfpack, tests/it/draco.rs runs pipeline/draco.mjs,
#   tests/it/ktx2.rs runs pipeline/ktx2.mjs.
set -eu
cd "$(dirname "$0")"
if [ "$(id -u)" -eq 0 ]; then sudo=""; else sudo="sudo"; fi

packages="mesa-vulkan-drivers libvulkan1 make"
command -v node >/dev/null 2>&1 && command -v npm >/dev/null 2>&1 || packages="$packages nodejs npm"
missing=""
for p in $packages; do
    dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"
done
if [ -n "$missing" ]; then
    echo "installing:$missing" >&2
    $sudo apt-get update -q
    $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -q $missing
fi

for tool in gltf-validator gltfpack @gltf-transform/core @gltf-transform/extensions draco3dgltf ktx2-encoder; do
    pinned=$(node -p "require('./package-lock.json').packages['node_modules/$tool'].version")
    installed=$(node -p "require('./node_modules/$tool/package.json').version" 2>/dev/null || true)
    if [ "$installed" != "$pinned" ]; then
        echo "installing: $tool $pinned and the other pinned tools (npm, into pipeline/node_modules)" >&2
        npm ci --no-audit --no-fund --loglevel=error
        break
    fi
done
