#!/usr/bin/env bash
# Rebuild meshcheck/reports/assets/three.min.js: three.js and its OrbitControls from the npm
# registry at a pinned version, bundled and minified by esbuild into one classic script (the
# report is opened from file://, where ES module imports of other files do not work).
# Needs node and npm. Run from anywhere; writes only into meshcheck/reports/assets/.
set -euo pipefail
THREE_VERSION=0.187.0
ESBUILD_VERSION=0.27.7
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
ASSETS="$ROOT/meshcheck/reports/assets"
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT

cd "$WORK"
npm init -y >/dev/null
npm install --no-audit --no-fund --save-exact "three@$THREE_VERSION" "esbuild@$ESBUILD_VERSION" >/dev/null
cp "$ROOT/scripts/three-entry.js" entry.js
npx esbuild entry.js --bundle --minify --format=iife --global-name=MeshcheckThree \
    --target=es2020 --legal-comments=inline --log-level=warning \
    --banner:js="/* three.js $THREE_VERSION (MIT, see three.LICENSE), bundled by scripts/build_three.sh */" \
    --outfile="$ASSETS/three.min.js"
cp node_modules/three/LICENSE "$ASSETS/three.LICENSE"
echo "$THREE_VERSION" > "$ASSETS/three.VERSION"
ls -l "$ASSETS/three.min.js"
