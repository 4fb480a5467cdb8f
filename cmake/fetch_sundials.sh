#!/usr/bin/env bash
# Fetches Debian's source package of the SUNDIALS version kneedyn is written against
# (bookworm's 6.4.1+dfsg1-3), checks its files against the checksums kept in this
# repository (cmake/sundials-source.sha256) and unpacks it with Debian's patches applied.
#   bash cmake/fetch_sundials.sh DEST    -> DEST/src (the patched source tree)
# Run by .ci/bootstrap before configuring, and by CMake (cmake/sundials.cmake) when DEST/src
# is missing. Needs a deb-src entry for bookworm; as root it adds one
# (/etc/apt/sources.list.d/kneedyn-deb-src.sources), otherwise it prints what to add.
# Idempotent: a verified DEST/src is left as it is.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
dest="${1:?usage: fetch_sundials.sh DEST}"
version="6.4.1+dfsg1-3"
stamp="$dest/src/.kneedyn-source-verified"
if [[ -f "$stamp" && "$(cat "$stamp")" == "$version" ]]; then
  exit 0
fi

have_source_index() { apt-cache showsrc sundials 2>/dev/null | grep -Fx "Version: $version" > /dev/null; }
if ! have_source_index; then
  if [[ $(id -u) -eq 0 ]]; then
    echo "[fetch_sundials] adding a deb-src entry for bookworm main" >&2
    cat > /etc/apt/sources.list.d/kneedyn-deb-src.sources <<'SRC'
Types: deb-src
URIs: http://deb.debian.org/debian
Suites: bookworm
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg
SRC
    apt-get update -qq -o DPkg::Lock::Timeout=600
  fi
  if ! have_source_index; then
    echo "fetch_sundials.sh: apt has no source package sundials=$version. Add a deb-src entry" \
         "for Debian bookworm main (e.g. the file above) and run 'apt-get update', or configure" \
         "with -DKNEEDYN_SUNDIALS=system to use Debian's binary (unoptimized) SUNDIALS." >&2
    exit 1
  fi
fi

download="$dest/download"
rm -rf "$download" "$dest/src"
mkdir -p "$download"
(cd "$download" && apt-get source --download-only -qq "sundials=$version" 2>/dev/null) || {
  echo "fetch_sundials.sh: 'apt-get source --download-only sundials=$version' failed" >&2; exit 1; }
# The checksums are this repository's, not the mirror's: a changed file is refused.
(cd "$download" && sha256sum --quiet --check "$here/sundials-source.sha256") || {
  echo "fetch_sundials.sh: the downloaded files do not match cmake/sundials-source.sha256" >&2; exit 1; }
# --no-check: the signature needs debian-keyring; every file was checked above instead.
dpkg-source --no-check -x "$download/sundials_$version.dsc" "$dest/src" > "$dest/unpack.log" 2>&1 || {
  echo "fetch_sundials.sh: dpkg-source failed (see $dest/unpack.log)" >&2; exit 1; }
echo "$version" > "$stamp"
echo "[fetch_sundials] SUNDIALS $version source in $dest/src" >&2
