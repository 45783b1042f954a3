#!/usr/bin/env bash
# The service as `cmake --install` installs it: staged into a temporary root (DESTDIR), every file in place, the
# unit accepted by `systemd-analyze verify` (its ExecStart resolved inside the stage), the system user and tmpfiles
# entries applied by systemd-sysusers/systemd-tmpfiles inside the stage, and the unit's exposure by
# `systemd-analyze security --offline=true` at most MAX (default 2.0).
# Usage: check_installed_unit.sh BUILD_DIR PREFIX [MAX]
set -euo pipefail
build=$1 prefix=$2 max=${3:-2.0}
stage=$(mktemp -d)
trap 'rm -rf "$stage"' EXIT
DESTDIR=$stage cmake --install "$build" >/dev/null
root=$stage$prefix
for f in bin/noisemond bin/noisemon lib/systemd/system/noisemond.service lib/sysusers.d/noisemon.conf \
         lib/tmpfiles.d/noisemon.conf lib/udev/rules.d/60-noisemon-comedi.rules etc/noisemon/noisemond.toml \
         etc/noisemon/noisemond.comedi.toml share/doc/noisemon/README.md share/doc/noisemon/docs/operator-guide.md; do
  [ -e "$root/$f" ] || { echo "not installed: $prefix/$f"; exit 1; }
done
unit=$root/lib/systemd/system/noisemond.service
grep -q "^ExecStart=$prefix/bin/noisemond --config $prefix/etc/noisemon/noisemond.toml\$" "$unit" \
  || { echo "ExecStart does not name the installed binary and configuration:"; grep ExecStart "$unit"; exit 1; }
# verify needs the binary where ExecStart says: the staged one.
mkdir -p "$stage/verify"
sed "s#^ExecStart=$prefix/bin/#ExecStart=$root/bin/#" "$unit" > "$stage/verify/noisemond.service"
systemd-analyze verify "$stage/verify/noisemond.service"
# The user and its home, created inside the stage as systemd would create them on the machine.
mkdir -p "$stage/etc"
systemd-sysusers --root="$stage" "$root/lib/sysusers.d/noisemon.conf"
grep -q '^noisemon:' "$stage/etc/passwd" || { echo "systemd-sysusers made no noisemon user"; exit 1; }
systemd-tmpfiles --root="$stage" --create "$root/lib/tmpfiles.d/noisemon.conf"
[ -d "$stage/var/lib/noisemon" ] || { echo "systemd-tmpfiles made no /var/lib/noisemon"; exit 1; }
report=$(systemd-analyze security --offline=true "$unit" 2>&1)
exposure=$(sed -n 's/.*Overall exposure level for noisemond.service: \([0-9.]*\).*/\1/p' <<<"$report")
[ -n "$exposure" ] || { echo "$report"; echo "no exposure figure"; exit 1; }
echo "noisemond.service exposure $exposure (limit $max)"
awk -v e="$exposure" -v m="$max" 'BEGIN { exit !(e <= m) }' || { echo "$report"; echo "exposure $exposure above $max"; exit 1; }
