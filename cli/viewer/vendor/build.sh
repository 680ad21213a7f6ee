#!/usr/bin/env bash
# Rebuilds three-subset.js from the npm registry's three and esbuild at the versions that
# package.json pins (package-lock.json records their checksums). Run after changing entry.js.
set -euo pipefail
cd "$(dirname "$0")"
npm ci --no-audit --no-fund
npm run build
cp node_modules/three/LICENSE LICENSE-three
rm -rf node_modules
