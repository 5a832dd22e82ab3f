#!/usr/bin/env bash
# Installs the @foxglove/ros2 peer's npm packages into this folder's node_modules (git-ignored),
# exactly as package-lock.json pins them (npm ci), and only when node_modules is missing or the
# lockfile changed since the last install: scripts/setup calls this on every run.
# Without npm it only says so: the peer's tests then skip.
#
# The pins (package.json): @foxglove/ros2 1.0.8 and the @foxglove packages peer.js uses directly
# (rosmsg 3.1.0, rosmsg2-serialization 1.1.1, rtps 1.6.0); tslib 2.9.1, which @foxglove/ros2's
# compiled code requires without declaring it; avl overridden to 1.5.3, since 1.6.0's CommonJS
# build has no default export and @foxglove/rtps's history caches then fail to construct.
set -euo pipefail
cd "$(dirname "$0")"

stamp=node_modules/.package-lock.sha256
if [ -f "$stamp" ] && sha256sum --status -c "$stamp" 2>/dev/null; then
  exit 0
fi
if ! command -v npm >/dev/null; then
  echo "foxglove peer: npm not found (Debian: nodejs npm); its tests will be skipped" >&2
  exit 0
fi
echo "foxglove peer: npm ci in $(pwd)"
npm ci --no-audit --no-fund --loglevel=error
sha256sum package-lock.json > "$stamp"
