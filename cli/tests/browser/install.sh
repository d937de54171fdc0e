#!/usr/bin/env bash
# Installs what the browser test (cli/tests/view.rs, pages_work_in_headless_chromium) needs:
# Debian's Chromium (no browser download by a test tool: this machine's network allows only
# the package registries) and playwright-core from npm (package-lock.json pins it). Without
# them the test skips with a message. Safe to run again.
set -euo pipefail
cd "$(dirname "$0")"
if [ ! -x /usr/bin/chromium ]; then
  if command -v apt-get >/dev/null && [ "$(id -u)" = 0 ]; then
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null
  else
    echo "cannot install chromium here (needs root and apt-get)" >&2
    exit 1
  fi
fi
command -v node >/dev/null || { echo "node not found" >&2; exit 1; }
npm ci --no-audit --no-fund --silent
/usr/bin/chromium --version
node -e "console.log('playwright-core', require('./node_modules/playwright-core/package.json').version)"
