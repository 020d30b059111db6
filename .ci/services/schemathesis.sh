#!/usr/bin/env bash
# Installs schemathesis (PyPI, a property-based API fuzzer) in a virtual environment of its own,
# for the omlox conformance run (crates/rtls-cli/tests/omlox_schemathesis.rs), which starts
# `rtls serve` on loopback and points schemathesis at it with the omlox hub OpenAPI.
#
# Usage:  eval "$(bash .ci/services/schemathesis.sh | tail -n 1)"
# The last line printed is always: export RTLS_SCHEMATHESIS=<path of the `st` command>
set -euo pipefail

version=4.32.5
venv=/opt/rtls-schemathesis
st="${venv}/bin/st"
if ! { [ -x "${st}" ] && "${st}" --version 2>/dev/null | grep -q "${version}"; }; then
    echo "schemathesis.sh: installing schemathesis ${version} (pip, into ${venv})" >&2
    python3 -m venv "${venv}" >&2
    "${venv}/bin/pip" install --quiet --disable-pip-version-check "schemathesis==${version}" >&2
fi
"${st}" --version >&2
echo "export RTLS_SCHEMATHESIS=${st}"
