#!/usr/bin/env sh
# Installs what bake and its tests need on Debian/Ubuntu, doing nothing that is
# already done:
# - the Vulkan loader and Mesa's drivers, whose lavapipe runs wgpu on the CPU
#   when there is no GPU;
# - make, which runs the build-step example (pipeline/Makefile) and its test;
# - Chromium, in which tests/it/engines.rs draws baked files with three.js and
#   Babylon.js (WebGL in software; without its recommended desktop packages);
# - Node.js (when there is no `node`), the Khronos glTF validator, gltfpack,
#   glTF-Transform with Google's Draco library and Binomial's Basis Universal
#   encoder (ktx2-encoder), from npm at the versions pinned in
#   pipeline/package-lock.json, into pipeline/node_modules (ignored by git);
#   tests/it/validator.rs runs the validator through pipeline/validate.mjs,
#   tests/it/gltfpack.rs runs gltfpack, tests/it/draco.rs runs pipeline/draco.mjs,
#   tests/it/ktx2.rs runs pipeline/ktx2.mjs; three.js, Babylon.js and
#   puppeteer-core, with which tests/it/engines.rs runs pipeline/engines.mjs;
#   Ajv, with which tests/it/report.rs runs pipeline/schema.mjs.
set -eu
cd "$(dirname "$0")"
if [ "$(id -u)" -eq 0 ]; then sudo=""; else sudo="sudo"; fi

packages="mesa-vulkan-drivers libvulkan1 make"
command -v node >/dev/null 2>&1 && command -v npm >/dev/null 2>&1 || packages="$packages nodejs npm"
missing=""
for p in $packages; do
    dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"
done
# Chromium alone without its recommended packages (a desktop's printing,
# notification and power services), which a headless test does not use.
browser=""
dpkg -s chromium >/dev/null 2>&1 || browser="chromium"
if [ -n "$missing$browser" ]; then
    echo "installing:$missing $browser" >&2
    $sudo apt-get update -q
    [ -z "$missing" ] || $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -q $missing
    [ -z "$browser" ] || $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends $browser
fi

# The first package of package.json whose installed version is not the one
# package-lock.json pins, if any (one node process for all of them).
stale=$(node -e '
const lock = require("./package-lock.json").packages;
for (const name of Object.keys(require("./package.json").dependencies)) {
    const pinned = lock["node_modules/" + name].version;
    let installed;
    try { installed = require("./node_modules/" + name + "/package.json").version; } catch {}
    if (installed !== pinned) { console.log(name + " " + pinned); break; }
}')
if [ -n "$stale" ]; then
    echo "installing: $stale and the other pinned tools (npm, into pipeline/node_modules)" >&2
    npm ci --no-audit --no-fund --loglevel=error
fi
