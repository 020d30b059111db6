#!/usr/bin/env bash
# Installs Debian's chromium for the dashboard's browser tests
# (crates/rtls-cli/tests/dashboard_browser.rs), which start it themselves: headless, no
# sandbox (CI runs as root), talking to `rtls serve` on loopback only.
#
# Usage:  eval "$(bash .ci/services/chromium.sh | tail -n 1)"
# The last line printed is always: export RTLS_CHROMIUM=<path of the binary>
set -euo pipefail

chromium_bin=$(command -v chromium || true)
if [ -z "${chromium_bin}" ]; then
    echo "chromium.sh: installing chromium (apt-get)" >&2
    export DEBIAN_FRONTEND=noninteractive
    if ! apt-get install -y --no-install-recommends chromium >&2; then
        apt-get update >&2
        apt-get install -y --no-install-recommends chromium >&2
    fi
    chromium_bin=$(command -v chromium)
fi
"${chromium_bin}" --version >&2
echo "export RTLS_CHROMIUM=${chromium_bin}"
