#!/bin/sh
# Builds the Debian package from the build folder (CPack) into a scratch folder and checks it: its
# files, its conffile, its maintainer scripts, and lintian's verdict (no errors).
#   package_check.sh BUILD_DIR   (exit 77: lintian or dpkg-deb is not installed)
set -eu
build=$1
for tool in cpack dpkg-deb lintian; do
  if ! command -v "$tool" >/dev/null 2>&1; then
    echo "skipped: $tool is not installed (scripts/setup.sh installs it)"
    exit 77
  fi
done
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
cpack -G DEB --config "$build/CPackConfig.cmake" -B "$out" >"$out/cpack.log" 2>&1 || { cat "$out/cpack.log"; exit 1; }
deb=$(ls "$out"/stampscan_*.deb)
echo "built $(basename "$deb") ($(du -h "$deb" | cut -f1))"
contents=$(dpkg-deb -c "$deb")
for f in ./usr/bin/station ./etc/stampscan/cell.toml ./lib/systemd/system/stampscan-panel.service \
         ./lib/udev/rules.d/60-stampscan-digitizer.rules ./usr/lib/sysctl.d/60-stampscan-gige.conf \
         ./usr/share/man/man1/station.1.gz \
         ./usr/share/doc/stampscan/copyright ./usr/share/doc/stampscan/changelog.gz ./usr/share/stampscan/materials.toml; do
  echo "$contents" | grep -q " $f\$" || { echo "FAILED: the package lacks $f"; exit 1; }
done
[ "$(dpkg-deb -f "$deb" Package)" = stampscan ] || { echo "FAILED: package name"; exit 1; }
dpkg-deb -I "$deb" conffiles | grep -qx /etc/stampscan/cell.toml || { echo "FAILED: cell.toml is not a conffile"; exit 1; }
for script in postinst prerm postrm; do
  dpkg-deb -I "$deb" "$script" >/dev/null || { echo "FAILED: no $script"; exit 1; }
done
dpkg-deb -f "$deb" Depends | grep -q "libjs-three" || { echo "FAILED: Depends lacks libjs-three"; exit 1; }
# The virtual cell's digitizer needs umockdev's preload library (the virtual cell of a fresh install).
dpkg-deb -f "$deb" Recommends | grep -q "umockdev" || { echo "FAILED: Recommends lacks umockdev"; exit 1; }
# lintian: errors fail, warnings are printed.
lintian --fail-on error --allow-root "$deb"
echo "lintian: no errors"
