#!/usr/bin/env bash
# A local PostgreSQL for the storage tests of rtls-server (`cargo test -p rtls-server --lib store`).
#
# On a Debian machine, as root: installs PostgreSQL if it is missing, starts a cluster without
# systemd (pg_ctlcluster, which falls back to pg_ctl), listening on 127.0.0.1:5432 only,
# creates the role `rtls` (password `rtls`) and the database `rtls_test` if they do not exist,
# offers TLS with a certificate for 127.0.0.1 from a test CA of its own, and prints the
# variables the tests read on its LAST line (everything else goes to stderr):
#
#     eval "$(bash .ci/services/postgres.sh | tail -1)"
#
# Running it again is harmless: whatever already exists is kept.
set -euo pipefail

readonly port=5432
readonly role=rtls
readonly password=rtls
readonly database=rtls_test
readonly cluster=main

log() { echo "postgres.sh: $*" >&2; }

if [ "$(id -u)" -ne 0 ]; then
    log "run me as root (I install packages and start the cluster as the postgres user)"
    exit 1
fi

if ! command -v pg_lsclusters >/dev/null 2>&1 || ! ls /usr/lib/postgresql/*/bin/postgres >/dev/null 2>&1; then
    log "installing postgresql"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq >&2
    apt-get install -y -qq postgresql >&2
fi

version="$(ls /usr/lib/postgresql | sort -V | tail -1)"
if ! pg_lsclusters -h | awk -v v="$version" -v c="$cluster" '$1 == v && $2 == c { found = 1 } END { exit !found }'; then
    log "creating cluster $version/$cluster"
    pg_createcluster "$version" "$cluster" >&2
fi

# TLS for the store's TLS test: a CA of its own and a server certificate for 127.0.0.1 signed
# by it (made once), so that a client verifying the chain and the address succeeds; the CA's
# path goes out with the URL.
tls_dir="/etc/postgresql/$version/$cluster/rtls-tls"
bash "$(dirname "$0")/test-certs.sh" "$tls_dir" "rtls test CA"
chown postgres:postgres "$tls_dir/server.key" "$tls_dir/server.crt"

# Loopback only, on the port the tests use, TLS offered (not required), in a file of its own
# under conf.d (which Debian's postgresql.conf includes last, so it wins); restart a running
# cluster when the file changes.
conf_dir="/etc/postgresql/$version/$cluster/conf.d"
conf_file="$conf_dir/rtls-test.conf"
wanted="listen_addresses = '127.0.0.1'
port = $port
ssl = on
ssl_cert_file = '$tls_dir/server.crt'
ssl_key_file = '$tls_dir/server.key'"
changed=0
if [ ! -f "$conf_file" ] || [ "$(cat "$conf_file")" != "$wanted" ]; then
    mkdir -p "$conf_dir"
    printf '%s\n' "$wanted" > "$conf_file"
    changed=1
fi

status="$(pg_lsclusters -h | awk -v v="$version" -v c="$cluster" '$1 == v && $2 == c { print $4 }')"
if [ "$status" = online ]; then
    if [ "$changed" -eq 1 ]; then
        log "restarting cluster $version/$cluster for the new settings"
        pg_ctlcluster "$version" "$cluster" restart >&2
    fi
else
    log "starting cluster $version/$cluster"
    pg_ctlcluster "$version" "$cluster" start >&2
fi

for _ in $(seq 1 30); do
    if pg_isready -q -h 127.0.0.1 -p "$port"; then
        break
    fi
    sleep 1
done
pg_isready -h 127.0.0.1 -p "$port" >&2

admin_psql() {
    runuser -u postgres -- psql --no-psqlrc -v ON_ERROR_STOP=1 -q -t -A -p "$port" "$@"
}

admin_psql -d postgres >&2 <<SQL
DO \$\$
BEGIN
    IF NOT EXISTS (SELECT FROM pg_roles WHERE rolname = '$role') THEN
        CREATE ROLE $role LOGIN CREATEDB PASSWORD '$password';
    ELSE
        ALTER ROLE $role LOGIN CREATEDB PASSWORD '$password';
    END IF;
END
\$\$;
SQL

if [ "$(admin_psql -d postgres -c "SELECT 1 FROM pg_database WHERE datname = '$database'")" != 1 ]; then
    log "creating database $database"
    admin_psql -d postgres -c "CREATE DATABASE $database OWNER $role" >&2
fi

url="postgres://$role:$password@127.0.0.1:$port/$database"
# Check that the role can log in over TCP with its password, as the tests will.
PGPASSWORD="$password" psql --no-psqlrc -v ON_ERROR_STOP=1 -q -t -A -h 127.0.0.1 -p "$port" -U "$role" -d "$database" \
    -c "SELECT 1" >/dev/null
log "ready: $url (TLS: CA $tls_dir/ca.crt)"
echo "export RTLS_TEST_POSTGRES_URL=$url RTLS_TEST_POSTGRES_CA=$tls_dir/ca.crt"
