#!/usr/bin/env bash
# Installs orbitflex's C library, header, pkg-config and CMake files under PREFIX (default
# /usr/local), after `cargo build --release -p orbitflex-capi`:
#   bash capi/install.sh "$HOME/.local"
set -euo pipefail
cd "$(dirname "$0")/.."
prefix="${1:-/usr/local}"
target="$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')/release"
install -d "$prefix/lib/pkgconfig" "$prefix/lib/cmake/orbitflex" "$prefix/include"
install -m 0755 "$target/liborbitflex_c.so" "$prefix/lib/"
[ -f "$target/liborbitflex_c.a" ] && install -m 0644 "$target/liborbitflex_c.a" "$prefix/lib/"
install -m 0644 include/orbitflex.h "$prefix/include/"
sed "s|@PREFIX@|$prefix|" capi/pkgconfig/orbitflex.pc.in > "$prefix/lib/pkgconfig/orbitflex.pc"
install -m 0644 capi/cmake/orbitflexConfig.cmake "$prefix/lib/cmake/orbitflex/"
echo "installed under $prefix: PKG_CONFIG_PATH=$prefix/lib/pkgconfig, CMAKE_PREFIX_PATH=$prefix"
