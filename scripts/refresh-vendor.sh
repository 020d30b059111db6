#!/usr/bin/env bash
# Refreshes the dashboard's vendored browser libraries from the npm registry — without Node:
# downloads each package's published tarball, checks it against the registry's sha512
# integrity, and copies the dist files it names into crates/rtls-server/assets/vendor/<package>/
# with the licence and a VERSION file. Usage: scripts/refresh-vendor.sh [leaflet@1.9.4 …]
# (no argument: the versions pinned below). Review the diff, rebuild, and run the browser tests.
set -euo pipefail
cd "$(dirname "$0")/.."
packages=("$@")
[ ${#packages[@]} -gt 0 ] || packages=(leaflet@1.9.4)
vendor=crates/rtls-server/assets/vendor
for spec in "${packages[@]}"; do
  name="${spec%@*}"
  version="${spec#*@}"
  meta="$(curl -fsS "https://registry.npmjs.org/$name/$version")"
  tarball="$(printf '%s' "$meta" | python3 -c 'import json,sys; print(json.load(sys.stdin)["dist"]["tarball"])')"
  integrity="$(printf '%s' "$meta" | python3 -c 'import json,sys; print(json.load(sys.stdin)["dist"]["integrity"])')"
  licence="$(printf '%s' "$meta" | python3 -c 'import json,sys; print(json.load(sys.stdin).get("license", "?"))')"
  work="$(mktemp -d)"
  curl -fsS "$tarball" -o "$work/package.tgz"
  actual="sha512-$(openssl dgst -sha512 -binary "$work/package.tgz" | base64 -w0)"
  if [ "$actual" != "$integrity" ]; then
    echo "$name@$version: integrity mismatch ($actual, registry says $integrity)" >&2
    exit 1
  fi
  tar -xzf "$work/package.tgz" -C "$work"
  case "$name" in
    leaflet) files=(dist/leaflet.js dist/leaflet.css LICENSE) ;;
    *) echo "no dist file list for $name: add one here" >&2; exit 1 ;;
  esac
  rm -rf "${vendor:?}/$name"
  mkdir -p "$vendor/$name"
  for file in "${files[@]}"; do cp "$work/package/$file" "$vendor/$name/"; done
  printf '%s %s\nlicence: %s\ntarball: %s\nintegrity: %s\n' "$name" "$version" "$licence" "$tarball" "$integrity" \
    > "$vendor/$name/VERSION"
  rm -rf "$work"
  echo "vendored $name@$version ($licence) into $vendor/$name"
done
