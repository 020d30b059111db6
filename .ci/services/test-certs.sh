#!/usr/bin/env bash
# Makes a test CA of its own and a server certificate for 127.0.0.1 (and localhost) signed by it,
# in DIR, unless DIR/server.crt exists: ca.crt, ca.key, server.crt, server.key. Used by the
# services that offer TLS to the tests (postgres.sh, mosquitto.sh), so that a client verifying
# the chain and the address succeeds. Installs openssl when it is missing (needs root).
#
# Usage:  bash .ci/services/test-certs.sh DIR "CA NAME"
set -euo pipefail
dir=$1
ca_name=${2:-rtls test CA}
[ -f "$dir/server.crt" ] && exit 0
if ! command -v openssl >/dev/null 2>&1; then
    echo "test-certs.sh: installing openssl (apt-get)" >&2
    export DEBIAN_FRONTEND=noninteractive
    apt-get install -y -qq openssl >&2 || { apt-get update -qq >&2; apt-get install -y -qq openssl >&2; }
fi
echo "test-certs.sh: making a test CA and a server certificate for 127.0.0.1 in $dir" >&2
mkdir -p "$dir"
openssl req -x509 -newkey rsa:2048 -nodes -days 3650 -subj "/CN=$ca_name" \
    -keyout "$dir/ca.key" -out "$dir/ca.crt" 2>/dev/null
openssl req -newkey rsa:2048 -nodes -subj "/CN=127.0.0.1" \
    -keyout "$dir/server.key" -out "$dir/server.csr" 2>/dev/null
printf 'subjectAltName=IP:127.0.0.1,DNS:localhost\nbasicConstraints=CA:FALSE\nextendedKeyUsage=serverAuth\n' \
    > "$dir/server.ext"
openssl x509 -req -in "$dir/server.csr" -CA "$dir/ca.crt" -CAkey "$dir/ca.key" \
    -CAcreateserial -days 3650 -extfile "$dir/server.ext" -out "$dir/server.crt" 2>/dev/null
chmod 644 "$dir/ca.crt" "$dir/server.crt"
chmod 600 "$dir/server.key"
