#!/usr/bin/env bash
# Bundles binaries built here for the GPU machine (the device tool), which has the CUDA toolkit and driver but
# none of our Debian libraries: copies each binary into .devbundle/bin/ and every shared library it needs
# (ldd) into .devbundle/lib/, except those any Linux system has (glibc's, libstdc++, libgcc_s) and the driver's
# libcuda, which must come from the GPU machine itself.
#
# Usage:  scripts/device_bundle.sh BINARY...            (e.g. build-cuda/tests/test_cuda)
# Env:    DEVBUNDLE_DIR=path         where to write (default: .devbundle at the repository root; emptied first)
#         DEVBUNDLE_LIBSTDCXX=1      bundle libstdc++ and libgcc_s too (if the GPU machine's are older than ours)
#         DEVBUNDLE_MAX_MIB=60       fail if the bundle is larger (what travels with a run is limited)
#         DEVBUNDLE_XZ=1             pack bin/ and lib/ into bundle.tar.xz (the CLI's libraries, OpenBLAS and gmsh among
#                                    them, are larger than a run carries); unpack there first:
#                                    tar -C .devbundle -xJf .devbundle/bundle.tar.xz
# Then, in a device run (carry=[".devbundle"]), from the repository root:
#         export LD_LIBRARY_PATH=$PWD/.devbundle/lib; .devbundle/bin/test_cuda
set -euo pipefail

root="$(cd "$(dirname "$0")/.." && pwd)"
dir="${DEVBUNDLE_DIR:-$root/.devbundle}"
max_mib="${DEVBUNDLE_MAX_MIB:-60}"
if [ "$#" -eq 0 ]; then
  echo "usage: $0 BINARY... (writes $dir)" >&2
  exit 2
fi

# The bundle must not travel as untracked files: it goes with carry, and never into a commit.
if [ "$dir" = "$root/.devbundle" ]; then
  exclude="$(git -C "$root" rev-parse --git-path info/exclude)"
  case "$exclude" in /*) ;; *) exclude="$root/$exclude" ;; esac
  mkdir -p "$(dirname "$exclude")"
  grep -qxF '/.devbundle/' "$exclude" 2>/dev/null || echo '/.devbundle/' >>"$exclude"
fi

# Libraries a bare system has, or that must be the GPU machine's own (the driver).
system_lib='^(linux-vdso|ld-linux|libc\.so|libm\.so|libmvec\.so|libpthread\.so|libdl\.so|librt\.so|libutil\.so|libresolv\.so|libcuda\.so|libnvidia-)'
if [ "${DEVBUNDLE_LIBSTDCXX:-0}" != 1 ]; then
  system_lib="${system_lib%)}|libstdc\\+\\+\\.so|libgcc_s\\.so)"
fi

rm -rf "$dir"
mkdir -p "$dir/bin" "$dir/lib"
for binary in "$@"; do
  [ -x "$binary" ] || { echo "not an executable: $binary" >&2; exit 1; }
  cp -L "$binary" "$dir/bin/"
  # "libfoo.so.1 => /path/libfoo.so.1 (0x...)": bundle under the name the loader asks for.
  while read -r name arrow path _; do
    [ "$arrow" = "=>" ] || continue
    if [ "$path" = "not" ]; then
      echo "$binary: $name not found here (ldd)" >&2
      exit 1
    fi
    if [[ "$name" =~ $system_lib ]]; then
      continue
    fi
    [ -e "$dir/lib/$name" ] || cp -L "$path" "$dir/lib/$name"
  done < <(ldd "$binary")
done

if [ "${DEVBUNDLE_XZ:-0}" = 1 ]; then
  tar -C "$dir" -cJf "$dir/bundle.tar.xz" bin lib
  rm -rf "$dir/bin" "$dir/lib"
fi
size_kib=$(du -sk "$dir" | cut -f1)
echo "bundle $dir: $(ls "$dir") $((size_kib / 1024)) MiB"
if [ "$size_kib" -gt $((max_mib * 1024)) ]; then
  echo "the bundle is larger than $max_mib MiB: link fewer libraries (-Wl,--as-needed, static archives)" >&2
  exit 1
fi
