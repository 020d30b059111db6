#!/usr/bin/env bash
# The NATS server for the cluster test of `rtls serve --cluster` (crates/rtls-cli/tests/cluster.rs)
# and the NATS forwarding test (crates/rtls-server/tests/nats_forward.rs).
#
# - installs Debian's nats-server when it is missing (needs root, as on the project's machines);
# - stops the system service the package may have started (the test starts its own three
#   servers, clustered with JetStream on free loopback ports, and kills them when it ends);
# - prints the variable the test reads on its LAST line:
#
#     eval "$(bash .ci/services/nats.sh | tail -1)"
set -euo pipefail

log() { echo "nats.sh: $*" >&2; }

if ! command -v nats-server >/dev/null 2>&1; then
    log "installing nats-server"
    export DEBIAN_FRONTEND=noninteractive
    apt-get install -y -qq nats-server >&2 || { apt-get update -qq >&2; apt-get install -y -qq nats-server >&2; }
fi
if command -v systemctl >/dev/null 2>&1; then
    systemctl disable --now nats-server >/dev/null 2>&1 || true
fi
binary="$(command -v nats-server)"
log "ready: $binary ($("$binary" --version))"
echo "export RTLS_TEST_NATS_SERVER=$binary"
