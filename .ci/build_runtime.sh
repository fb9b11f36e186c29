#!/usr/bin/env bash
# Builds the C API / FMU runtime (the `capi/` workspace member) and copies it into
# python/orbitflex/_runtime/, where `[tool.maturin] include` puts it in the wheel.
#
#   bash .ci/build_runtime.sh
#
# `pip install .` does this through the in-tree build backend (build_backend/). The release
# workflow calls `maturin build` directly (through maturin-action), which skips the backend, so it
# runs this script first: inside the manylinux container on Linux, on the runner elsewhere.
# Honours CARGO_BUILD_TARGET (the library is then under target/<triple>/release).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -p orbitflex-capi
dir=target/${CARGO_BUILD_TARGET:+$CARGO_BUILD_TARGET/}release
mkdir -p python/orbitflex/_runtime
for name in liborbitflex_c.so liborbitflex_c.dylib orbitflex_c.dll; do
  if [ -f "$dir/$name" ]; then
    cp "$dir/$name" python/orbitflex/_runtime/
    echo "build_runtime: $dir/$name -> python/orbitflex/_runtime/"
    exit 0
  fi
done
echo "build_runtime: cargo built orbitflex-capi but no runtime library is in $dir" >&2
exit 1
