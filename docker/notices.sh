#!/bin/sh
# SPDX-License-Identifier: MIT
# docker/notices.sh HEADER - the image's third-party notice on stdout: HEADER
# (docker/THIRD-PARTY-NOTICES: mcfd's licence, what it links and under which
# licence), then one line per Debian package installed where it runs: name,
# version, the licences its copyright file names. docker/Dockerfile runs it
# in the runtime stage, after the last package is installed, into
# /usr/share/doc/mcfd/THIRD-PARTY-NOTICES; `make image-check` checks that
# file against the image's package database. POSIX sh, coreutils and sed.
set -eu
cat "$1"
echo
tab=$(printf '\t')
dpkg-query -W -f '${Package}\t${Version}\n' | sort | while IFS=$tab read -r pkg ver; do
    f=/usr/share/doc/$pkg/copyright
    if [ ! -f "$f" ]; then
        lic="no copyright file"
    elif grep -q '^Format: ' "$f"; then
        lic=$(sed -n 's/^License: *\(..*\)$/\1/p' "$f" | sort -u | paste -sd '|' - | sed 's/|/; /g')
    else
        lic="see the copyright file"
    fi
    printf '%-32s %-36s %s\n' "$pkg" "$ver" "${lic:-see the copyright file}"
done
