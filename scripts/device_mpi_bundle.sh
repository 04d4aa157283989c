#!/usr/bin/env bash
# Bundles Debian's OpenMPI (mpirun, orted, their MCA and PMIx components, help texts) for the GPU machine, which
# has none (issue 18's scaling figures there): into .devbundle/ompi, beside scripts/device_bundle.sh's bundle
# (run that first: it empties .devbundle). OpenMPI finds its relocated parts through the OPAL_* and PMIX_*
# variables that .devbundle/ompi/env.sh sets.
#
# Usage:  scripts/device_mpi_bundle.sh
# Then, in a device run (carry=[".devbundle"]), from the repository root:
#         tar -C .devbundle -xJf .devbundle/ompi.tar.xz; . .devbundle/ompi/env.sh; mpirun -n 4 ...
set -euo pipefail

root="$(cd "$(dirname "$0")/.." && pwd)"
dir="${DEVBUNDLE_DIR:-$root/.devbundle}"
ompi="$dir/ompi"
libdir=/usr/lib/x86_64-linux-gnu
rm -rf "$ompi"
mkdir -p "$ompi/bin" "$ompi/lib" "$ompi/share"
cp -L /usr/bin/orterun "$ompi/bin/mpirun"
cp -L /usr/bin/orted "$ompi/bin/orted"
cp -rL "$libdir/openmpi/lib/openmpi3" "$ompi/openmpi3"
cp -rL "$libdir/pmix2/lib/pmix" "$ompi/pmix"
cp -rL /usr/share/openmpi "$ompi/share/openmpi"
[ -d /usr/share/pmix ] && cp -rL /usr/share/pmix "$ompi/share/pmix"
mkdir -p "$ompi/etc"
cp -L /etc/openmpi/openmpi-mca-params.conf "$ompi/etc/" 2>/dev/null || true

# Every library the programs and components need, but those any Linux system has.
system_lib='^(linux-vdso|ld-linux|libc\.so|libm\.so|libmvec\.so|libpthread\.so|libdl\.so|librt\.so|libutil\.so|libresolv\.so|libstdc\+\+\.so|libgcc_s\.so|libcuda\.so|libnvidia-)'
for object in "$ompi"/bin/* "$ompi"/openmpi3/*.so "$ompi"/pmix/*.so; do
  while read -r name arrow path _; do
    [ "$arrow" = "=>" ] || continue
    [ "$path" = "not" ] && { echo "$object: $name not found here (ldd)" >&2; exit 1; }
    [[ "$name" =~ $system_lib ]] && continue
    [ -e "$ompi/lib/$name" ] || cp -L "$path" "$ompi/lib/$name"
  done < <(ldd "$object")
done

cat >"$ompi/env.sh" <<'EOF'
# Source from the repository root on the GPU machine: Debian's OpenMPI from .devbundle/ompi.
B="$PWD/.devbundle/ompi"
export PATH="$B/bin:$PATH" LD_LIBRARY_PATH="$B/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export OPAL_PREFIX="$B" OPAL_BINDIR="$B/bin" OPAL_LIBDIR="$B/lib" OPAL_PKGLIBDIR="$B/openmpi3" \
  OPAL_PKGDATADIR="$B/share/openmpi" OPAL_DATADIR="$B/share" OPAL_DATAROOTDIR="$B/share" OPAL_SYSCONFDIR="$B/etc"
export OMPI_MCA_mca_base_component_path="$B/openmpi3" PMIX_MCA_mca_base_component_path="$B/pmix"
export PMIX_INSTALL_PREFIX="$B" OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
# PMIx also tries the components' build-time folder (there, a system one may exist): not an error worth a line.
export OMPI_MCA_mca_base_component_show_load_errors=0 PMIX_MCA_mca_base_component_show_load_errors=0
EOF
tar -C "$dir" -cJf "$dir/ompi.tar.xz" ompi
rm -rf "$ompi"
echo "$dir/ompi.tar.xz: $(du -h "$dir/ompi.tar.xz" | cut -f1)"
