#!/usr/bin/env bash
# Starts a local mosquitto broker for the external-broker tests of rtls-server
# (crates/rtls-server/tests/mqtt_mosquitto.rs).
#
# - installs Debian's mosquitto when it is missing (needs root, as on the project's machines),
#   and mosquitto-clients and curl for the TLS test;
# - runs it as a background daemon (not through systemd) with its own configuration in a
#   temporary directory: one listener on 127.0.0.1:18830, and one with TLS on 127.0.0.1:18831
#   (a test CA and a certificate for 127.0.0.1 made once with openssl in /tmp/rtls-mosquitto-tls),
#   anonymous clients allowed, no persistence;
# - waits until the port accepts connections;
# - does nothing but print the variable when a broker already answers on that port.
#
# Usage:  eval "$(bash .ci/services/mosquitto.sh | tail -n 1)"
# The last line printed is always: export RTLS_TEST_MOSQUITTO_URL=mqtt://127.0.0.1:18830
#   RTLS_TEST_MOSQUITTOS_URL=mqtts://127.0.0.1:18831 RTLS_TEST_MOSQUITTO_CA=<the test CA's PEM>
set -euo pipefail

host=127.0.0.1
port=18830
tls_port=18831
url="mqtt://${host}:${port}"
tls_dir=/tmp/rtls-mosquitto-tls
exports="export RTLS_TEST_MOSQUITTO_URL=${url} RTLS_TEST_MOSQUITTOS_URL=mqtts://${host}:${tls_port} RTLS_TEST_MOSQUITTO_CA=${tls_dir}/ca.crt"

# the TLS test of `rtls serve` (crates/rtls-cli/tests/serve_tls.rs) drives real clients
if ! command -v mosquitto_pub >/dev/null || ! command -v curl >/dev/null; then
    echo "mosquitto.sh: installing mosquitto-clients and curl (apt-get)" >&2
    export DEBIAN_FRONTEND=noninteractive
    if ! apt-get install -y --no-install-recommends mosquitto-clients curl >&2; then
        apt-get update >&2
        apt-get install -y --no-install-recommends mosquitto-clients curl >&2
    fi
fi

port_accepts() {
    # bash's /dev/tcp: succeeds when something accepts a TCP connection on host:port.
    (exec 3<>"/dev/tcp/${host}/${port}") 2>/dev/null
}

if port_accepts; then
    echo "mosquitto.sh: a broker already accepts connections on ${host}:${port}" >&2
    echo "${exports}"
    exit 0
fi

# TLS for the bridge's TLS test: a CA of its own and a certificate for 127.0.0.1 signed by it.
bash "$(dirname "$0")/test-certs.sh" "${tls_dir}" "rtls mosquitto test CA"
# the broker runs as the user "mosquitto" when started as root: it must read its key
chmod 644 "${tls_dir}/server.key"

mosquitto_bin=$(command -v mosquitto || true)
if [ -z "${mosquitto_bin}" ] && [ -x /usr/sbin/mosquitto ]; then
    mosquitto_bin=/usr/sbin/mosquitto
fi
if [ -z "${mosquitto_bin}" ]; then
    echo "mosquitto.sh: installing mosquitto (apt-get)" >&2
    export DEBIAN_FRONTEND=noninteractive
    if ! apt-get install -y --no-install-recommends mosquitto >&2; then
        apt-get update >&2
        apt-get install -y --no-install-recommends mosquitto >&2
    fi
    mosquitto_bin=$(command -v mosquitto || echo /usr/sbin/mosquitto)
fi

work_dir=$(mktemp -d /tmp/rtls-mosquitto.XXXXXX)
config="${work_dir}/mosquitto.conf"
cat >"${config}" <<CONF
# Written by .ci/services/mosquitto.sh for the rtls-server tests.
per_listener_settings false
allow_anonymous true
listener ${port} ${host}
listener ${tls_port} ${host}
cafile ${tls_dir}/ca.crt
certfile ${tls_dir}/server.crt
keyfile ${tls_dir}/server.key
persistence false
pid_file ${work_dir}/mosquitto.pid
log_dest file ${work_dir}/mosquitto.log
log_type error
log_type warning
log_type notice
CONF
# Debian's package runs the broker as the user "mosquitto" when started as root; let it write
# its pid and log files.
if id mosquitto >/dev/null 2>&1; then
    chown -R mosquitto "${work_dir}"
fi

"${mosquitto_bin}" -c "${config}" -d

for _ in $(seq 1 100); do
    if port_accepts; then
        echo "mosquitto.sh: mosquitto runs on ${host}:${port} (config and log in ${work_dir})" >&2
        echo "${exports}"
        exit 0
    fi
    sleep 0.1
done

echo "mosquitto.sh: mosquitto did not accept connections on ${host}:${port} within 10 s; its log:" >&2
cat "${work_dir}/mosquitto.log" >&2 || true
exit 1
