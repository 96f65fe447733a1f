#!/usr/bin/env bash
# cmake --install into a scratch prefix: the installed penumbra runs (--version, a bake of the
# default scene), and the man page, README and scene-format reference are where the man page
# says they are. Usage: install_tree.sh BUILD_DIR
set -euo pipefail
build=$1
prefix=$(mktemp -d "${TMPDIR:-/tmp}/penumbra-install-XXXXXX")
trap 'rm -rf "$prefix"' EXIT
cmake --install "$build" --prefix "$prefix" >/dev/null
"$prefix/bin/penumbra" --version | grep -q '^penumbra 0\.' || { echo "installed penumbra --version failed"; exit 1; }
for f in share/man/man1/penumbra.1 share/doc/penumbra/README.md share/doc/penumbra/docs/scene-format.md \
         share/doc/penumbra/docs/design.md; do
  [ -s "$prefix/$f" ] || { echo "missing after install: $f"; exit 1; }
done
[ ! -e "$prefix/share/doc/penumbra/docs/man" ] || { echo "the man page folder was installed as a doc"; exit 1; }
if command -v man >/dev/null 2>&1; then
  MANPATH="$prefix/share/man" man -P cat penumbra 2>/dev/null | grep -q "out-of-core soft-shadow baker" ||
    { echo "man penumbra does not render the page"; exit 1; }
fi
src=$(cd "$(dirname "$0")/../.." && pwd)
mkdir -p "$prefix/run/out"
"$prefix/bin/penumbra" bake "$src/examples/grids.json" -q --threads 2 -o "$prefix/run/out/g.exr" --allow-outside-uris
[ -s "$prefix/run/out/g.exr" ] && [ -s "$prefix/run/out/g.png" ] || { echo "the installed penumbra wrote no bake"; exit 1; }
# The volume receivers are a plugin (lib/penumbra/penumbra_volume.so): the installed CLI finds it.
"$prefix/bin/penumbra" bake "$src/examples/volume.json" -q -o "$prefix/run/out/v.vdb" --allow-outside-uris
[ -s "$prefix/run/out/v.vdb" ] || { echo "the installed penumbra wrote no volume"; exit 1; }
echo "install tree OK"
