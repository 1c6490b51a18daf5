#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Installs the journal tests' independent MCAP reader (read.js with @mcap/core and the ROS 2 CDR
# decoder, at the versions package-lock.json pins) from the npm registry into DEST, with Debian's
# Node.js (scripts/setup.sh installs it). Idempotent: nothing is fetched when DEST already holds
# this lock file's packages. CTest runs it as the fixture of the journal tests.
# Usage: install.sh DEST
set -euo pipefail
src=$(cd "$(dirname "$0")" && pwd)
dest=${1:?usage: install.sh DEST}
for tool in node npm; do
  if ! command -v "$tool" >/dev/null 2>&1; then
    echo "mcap-reader: '$tool' is missing (scripts/setup.sh installs Debian's nodejs and npm)" >&2
    exit 1
  fi
done
mkdir -p "$dest"
cp "$src/package.json" "$src/package-lock.json" "$src/read.js" "$dest/"
stamp="$dest/node_modules/.scanmesh-lock.sha256"
want=$(sha256sum "$src/package-lock.json" | cut -d' ' -f1)
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ]; then
  echo "mcap-reader: up to date in $dest"
  exit 0
fi
cd "$dest"
npm ci --no-audit --no-fund --loglevel=error
echo "$want" >"$stamp"
echo "mcap-reader: installed in $dest ($(node --version))"
