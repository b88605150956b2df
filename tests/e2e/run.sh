#!/usr/bin/env bash
# CTest web_e2e: the museum-guide web client in a real browser (browser_test.mjs);
# web_admin_e2e: the admin page (run.sh admin_test.mjs).
# Installs what it needs when missing: Debian's chromium (apt, sudo when not root) and
# playwright-core as pinned in package-lock.json (npm ci into tests/e2e/node_modules;
# no browser download). Env: MVKP=<mvkp binary>, SAMPLES=<repo>/samples; optional OUT
# (directory for screenshots, default the binary's directory) and E2E_SCREENSHOT.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi

if [ ! -x /usr/bin/chromium ]; then
  echo "web_e2e: /usr/bin/chromium missing, installing Debian's chromium"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends chromium
fi

if [ ! -f "$here/node_modules/playwright-core/package.json" ]; then
  echo "web_e2e: installing playwright-core (npm ci)"
  if ! command -v npm >/dev/null; then
    export DEBIAN_FRONTEND=noninteractive
    $SUDO apt-get update -qq
    $SUDO apt-get install -y -qq --no-install-recommends npm
  fi
  (cd "$here" && PLAYWRIGHT_SKIP_BROWSER_DOWNLOAD=1 npm ci --no-audit --no-fund)
fi

exec node "$here/${1:-browser_test.mjs}"  # or another test script, e.g. admin_test.mjs
