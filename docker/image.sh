#!/bin/sh
# SPDX-License-Identifier: MIT
# docker/image.sh - build and check the mcfd container image with Debian's podman.
#
#   docker/image.sh build IMAGE [BASE]   build docker/Dockerfile as IMAGE (make image)
#   docker/image.sh check IMAGE MCF      run IMAGE as CI does (make image-check); MCF is the
#                                        mcf tool, used to decode what the container returns
#   docker/image.sh setup                the host settings below, when this machine needs them
#   docker/image.sh podman ARGS...       podman, for anything else
#
# Run from the top of the repository, as root (CI and the development machines are root).
#
# Why the settings (seen on these machines, Debian bookworm, podman 4.3.1, cgroups v1, root
# inside a sandbox whose hard limits are below what rootful podman asks for):
#  - crun, podman's preferred OCI runtime, fails here: first "setrlimit RLIMIT_NOFILE:
#    Operation not permitted", then "cgroups in hybrid mode". runc works (`make image`
#    installs runc, not crun).
#  - runc fails too ("error setting rlimit type 7: operation not permitted": `podman run`
#    exits 126) while rootful podman asks for its default ulimits (nofile 1048576, nproc
#    4194304), which are above the sandbox's hard limits. With the containers' default
#    ulimits at nofile = the host's hard limit (20000 here) and nproc 4096 it works.
#  - So that a plain `podman run` works as the README shows it, both settings go into a
#    drop-in podman reads for root, /etc/containers/containers.conf.d/50-mcfd-sandbox.conf,
#    written by `setup` (which build and check run first) only where the host cannot raise
#    its own limits to podman's defaults; an ordinary host gets no file. It changes the
#    defaults of root's podman on such a host, and says so when it writes it.
#  - No container registry is reachable from these machines (only the Debian archive is), so
#    `podman pull debian:bookworm-slim` fails. The base is then made here:
#    `debootstrap --variant=minbase bookworm` from the Debian archive, trimmed like the slim
#    image (no apt lists or .deb cache, no docs but copyright files, no man pages or
#    locales) and `podman import`ed as localhost/mcfd-base:bookworm. It stays in podman's
#    store, so later builds on the machine reuse it (31 s to make, 5 s to import).
#  - `podman build --format docker`: the default OCI format drops HEALTHCHECK.
#  - Publishing a loopback port (-p 127.0.0.1:PORT:8080) works with podman's default network.
set -eu

LOCAL_BASE=localhost/mcfd-base:bookworm
MIRROR=${DEBIAN_MIRROR:-http://deb.debian.org/debian}

DROPIN=/etc/containers/containers.conf.d/50-mcfd-sandbox.conf

pm() { podman "$@"; }

# The drop-in, where rootful podman's default ulimits are above what this host allows
# (see above); nothing on a host that can raise its limits to them, or for a non-root user
# (rootless podman asks only for the user's own limits).
setup() {
    [ "$(id -u)" = 0 ] || return 0
    if bash -c 'ulimit -Hn 1048576 && ulimit -Hu 4194304' 2>/dev/null; then
        return 0
    fi
    # nofile: the host's hard limit, at most 65536; nproc: 4096, plenty for mcfd's threads
    # (at the host's hard nproc, 96365 here, runc still failed with "rlimit type 6")
    nofile=$(bash -c 'n=$(ulimit -Hn); [ "$n" = unlimited ] || [ "$n" -gt 65536 ] && n=65536; echo $n')
    nproc=4096
    want=$(printf '%s\n' \
        "# Written by mcfd's docker/image.sh (make image): this host's hard limits" \
        "# (nofile $nofile, nproc $nproc) are below rootful podman's default ulimits, and" \
        "# runc then fails every container with \"error setting rlimit type 7\"." \
        "[containers]" \
        "default_ulimits = [\"nofile=$nofile:$nofile\", \"nproc=$nproc:$nproc\"]" \
        "" "[engine]" "runtime = \"runc\"")
    if [ "$(cat "$DROPIN" 2>/dev/null)" != "$want" ]; then
        mkdir -p "$(dirname "$DROPIN")"
        printf '%s\n' "$want" > "$DROPIN.tmp" && mv "$DROPIN.tmp" "$DROPIN"
        echo "image.sh: wrote $DROPIN (podman's default ulimits above this host's hard limits)" >&2
    fi
}

now() { date +%s; }

# The base image: $1 when given; debian:bookworm-slim when it can be pulled (or is there);
# else the debootstrap import, made once.
base_image() {
    if [ -n "${1:-}" ]; then
        echo "$1"
        return
    fi
    if pm image exists docker.io/library/debian:bookworm-slim ||
       pm pull -q docker.io/library/debian:bookworm-slim >/dev/null 2>&1; then
        echo docker.io/library/debian:bookworm-slim
        return
    fi
    if ! pm image exists "$LOCAL_BASE"; then
        t0=$(now)
        root=$(mktemp -d "${TMPDIR:-/tmp}/mcfd-rootfs.XXXXXX")
        echo "image.sh: no registry; making $LOCAL_BASE with debootstrap" >&2
        debootstrap --variant=minbase bookworm "$root" "$MIRROR" >"$root.log" 2>&1 ||
            { tail -20 "$root.log" >&2; rm -rf "$root" "$root.log"; exit 1; }
        # trimmed like debian:bookworm-slim, and kept so by dpkg for what apt adds later
        rm -rf "$root"/var/cache/apt/archives/*.deb "$root"/var/lib/apt/lists/* \
               "$root"/usr/share/man/* "$root"/usr/share/locale/* "$root"/usr/share/info/*
        find "$root/usr/share/doc" -mindepth 1 ! -name copyright ! -type d -delete
        cat > "$root/etc/dpkg/dpkg.cfg.d/slim" <<'EOF'
path-exclude /usr/share/doc/*
path-include /usr/share/doc/*/copyright
path-exclude /usr/share/man/*
path-exclude /usr/share/locale/*
path-exclude /usr/share/info/*
EOF
        tar -C "$root" -c . | pm import -q - "$LOCAL_BASE" >/dev/null
        rm -rf "$root" "$root.log"
        echo "image.sh: $LOCAL_BASE made in $(( $(now) - t0 )) s" >&2
    fi
    echo "$LOCAL_BASE"
}

build() {
    setup
    image=$1
    t0=$(now)
    base=$(base_image "${2:-}")
    echo "image.sh: building $image on $base"
    pm build --format docker --layers --build-arg BASE="$base" \
        -f docker/Dockerfile -t "$image" .
    echo "image.sh: $image built in $(( $(now) - t0 )) s"
}

check() {
    setup
    image=$1 mcf=$2
    name=mcfd-check-$$
    out=$(mktemp -d "${TMPDIR:-/tmp}/mcfd-check.XXXXXX")
    trap 'pm rm -f -t 0 "$name" >/dev/null 2>&1 || true; rm -rf "$out"' EXIT
    t0=$(now)
    # --health-interval=disable: podman's periodic health timer needs systemd, which these
    # machines do not run; the HEALTHCHECK (mcfd --probe) is run by hand below instead.
    # (podman 4.3 still says so on stderr: kept in $out/podman.err, shown on a failure)
    # -p 127.0.0.1::8080: a free loopback port, read back with podman port
    # --memory 1g: the default --max-memory must follow the container's limit, not the host's RAM
    pm run -d --name "$name" --health-interval=disable --memory 1g \
        -p 127.0.0.1::8080 -p 127.0.0.1::50051 "$image" \
        >/dev/null 2>"$out/podman.err" || { cat "$out/podman.err" >&2; exit 1; }
    port=$(pm port "$name" 8080/tcp | sed -n 's/^127\.0\.0\.1:\([0-9]*\)$/\1/p')
    [ -n "$port" ] || { pm port "$name" >&2; echo "image-check: FAIL: no loopback port" >&2; exit 1; }
    i=0
    until pm healthcheck run "$name" >/dev/null 2>&1; do
        i=$((i + 1))
        if [ $i -ge 60 ]; then
            pm logs "$name" >&2 || true
            echo "image-check: FAIL: the healthcheck did not pass within 30 s" >&2
            exit 1
        fi
        sleep 0.5
    done
    echo "image-check: healthcheck (mcfd --probe) passes"
    mm=$(pm logs "$name" 2>&1 | sed -n 's/.*"max_memory":\([0-9]*\).*/\1/p' | head -1)
    [ "$mm" = 536870912 ] ||
        { echo "image-check: FAIL: max_memory '$mm' under --memory 1g, want half of it (536870912)" >&2; exit 1; }
    echo "image-check: under --memory 1g the default --max-memory is 512 MiB (half the cgroup limit)"
    # the processes themselves, seen from the host: tini (PID 1) and mcfd under it
    pid=$(pm inspect --format '{{.State.Pid}}' "$name")
    ps -o uid=,args= -p "$pid" --ppid "$pid" > "$out/procs"
    grep -q 'mcfd' "$out/procs" || { cat "$out/procs" >&2; echo "image-check: FAIL: no mcfd process" >&2; exit 1; }
    if awk '$1 == 0 { bad = 1 } END { exit !bad }' "$out/procs"; then
        cat "$out/procs" >&2; echo "image-check: FAIL: a process runs as root" >&2; exit 1
    fi
    echo "image-check: tini and mcfd run as uid $(awk 'NR == 1 { print $1 }' "$out/procs") ($(pm exec "$name" id -un)), not root"
    # the licence and the third-party notice: every Debian package of the image listed
    pm exec "$name" cat /usr/share/doc/mcfd/LICENSE /usr/share/doc/mcfd/THIRD-PARTY-NOTICES \
        /usr/share/doc/mcfd/three.js-LICENSE \
        > "$out/notices" || { echo "image-check: FAIL: no licence or notice in the image" >&2; exit 1; }
    pm exec "$name" dpkg-query -W -f '${Package}\n' > "$out/packages"
    missing=$(while read -r p; do grep -q "^$p " "$out/notices" || echo "$p"; done < "$out/packages")
    [ -z "$missing" ] && grep -q '^MIT License$' "$out/notices" ||
        { echo "image-check: FAIL: the notice misses: $missing" >&2; exit 1; }
    echo "image-check: /usr/share/doc/mcfd has the MIT licence and a notice naming all $(wc -l < "$out/packages") Debian packages"
    code=$(curl -sS -o "$out/smoothed.obj" -w '%{http_code}' --max-time 60 \
        -F mesh=@tests/data/meshes/sphere_cgal.obj \
        "http://127.0.0.1:$port/smooth?scheme=desbrun2&iterations=5")
    [ "$code" = 200 ] || { echo "image-check: FAIL: POST /smooth: HTTP $code" >&2; exit 1; }
    "$mcf" info "$out/smoothed.obj" > "$out/info.json" ||
        { echo "image-check: FAIL: the smoothed mesh does not decode" >&2; exit 1; }
    grep -Eq '"vertices":[[:space:]]*812,' "$out/info.json" ||
        { echo "image-check: FAIL: not the sphere's 812 vertices:" >&2; cat "$out/info.json" >&2; exit 1; }
    echo "image-check: POST /smooth on 127.0.0.1:$port returned a mesh of 812 vertices that decodes"
    # a Draco upload: decoded in the sandboxed child (posix_spawn of /proc/self/exe) inside the container
    code=$(curl -sS -o "$out/smoothed.drc" -w '%{http_code}' --max-time 120 \
        -F mesh=@tests/data/meshes/bunny.drc "http://127.0.0.1:$port/smooth")
    [ "$code" = 200 ] || { cat "$out/smoothed.drc" >&2; echo "image-check: FAIL: POST /smooth bunny.drc: HTTP $code" >&2; exit 1; }
    "$mcf" info "$out/smoothed.drc" | grep -Eq '"vertices":[[:space:]]*34834,' ||
        { echo "image-check: FAIL: the smoothed bunny.drc is not the bunny's 34834 vertices" >&2; exit 1; }
    echo "image-check: POST /smooth of bunny.drc (a sandboxed Draco decode) returned the bunny's 34834 vertices"
    # the page (issue 21): embedded at build time, served without node in the image
    code=$(curl -sS -o "$out/page.html" -w '%{http_code}' --max-time 10 "http://127.0.0.1:$port/")
    [ "$code" = 200 ] && grep -q '/ui/app.js' "$out/page.html" ||
        { echo "image-check: FAIL: GET /: HTTP $code" >&2; exit 1; }
    code=$(curl -sS -o "$out/three.js" -w '%{http_code}' --max-time 10 "http://127.0.0.1:$port/ui/three.core.js")
    [ "$code" = 200 ] && [ "$(wc -c < "$out/three.js")" -gt 100000 ] ||
        { echo "image-check: FAIL: GET /ui/three.core.js: HTTP $code" >&2; exit 1; }
    echo "image-check: GET / serves the page and /ui/three.core.js its three.js"
    # the gRPC door: Smooth through the published port with the example client
    gport=$(pm port "$name" 50051/tcp | sed -n 's/^127\.0\.0\.1:\([0-9]*\)$/\1/p')
    /usr/bin/python3 examples/grpc_client.py --addr "127.0.0.1:$gport" --scheme desbrun2 --iterations 5 \
        tests/data/meshes/sphere_cgal.obj "$out/grpc.obj" > "$out/grpc.log" 2>&1 ||
        { cat "$out/grpc.log" >&2; echo "image-check: FAIL: gRPC Smooth on port $gport" >&2; exit 1; }
    cmp -s "$out/grpc.obj" "$out/smoothed.obj" ||
        { echo "image-check: FAIL: gRPC and REST results differ" >&2; exit 1; }
    echo "image-check: gRPC Smooth on 127.0.0.1:$gport returned the same bytes as POST /smooth"
    # the descriptors under the container's nofile limit (1024 with the settings above): 1010
    # gRPC connections that send only the HTTP/2 preface (issue 17 item 1) are held for 4 s;
    # the doors' caps are fitted to the limit (logged), so the healthcheck passes meanwhile and
    # gRPC serves after
    pm logs "$name" 2>&1 | sed -n 's/.*"msg":"\(RLIMIT_NOFILE[^"]*\)".*/image-check: mcfd says: \1/p'
    /usr/bin/python3 tests/h2raw.py flood 127.0.0.1 "$gport" 1010 4 > "$out/flood.log" 2>&1 &
    flood=$!
    sleep 2
    pm healthcheck run "$name" >/dev/null 2>&1 ||
        { pm logs "$name" 2>&1 | tail -20 >&2; echo "image-check: FAIL: the healthcheck failed during a flood of idle gRPC connections" >&2; exit 1; }
    wait $flood || { cat "$out/flood.log" >&2; echo "image-check: FAIL: the flood client" >&2; exit 1; }
    /usr/bin/python3 examples/grpc_client.py --addr "127.0.0.1:$gport" --scheme desbrun2 --iterations 5 \
        tests/data/meshes/sphere_cgal.obj "$out/grpc2.obj" > "$out/grpc.log" 2>&1 ||
        { cat "$out/grpc.log" >&2; echo "image-check: FAIL: gRPC Smooth after the flood" >&2; exit 1; }
    echo "image-check: 1010 idle gRPC connections ($(cat "$out/flood.log")): the healthcheck passed meanwhile, gRPC Smooth works after"
    pm stop -t 40 "$name" >/dev/null 2>>"$out/podman.err" || { cat "$out/podman.err" >&2; exit 1; }
    st=$(pm inspect "$name" --format '{{.State.ExitCode}}')
    [ "$st" = 0 ] || { pm logs "$name" | tail -20 >&2; echo "image-check: FAIL: exit status $st after podman stop" >&2; exit 1; }
    echo "image-check: podman stop: exit status 0 (drained)"
    size=$(pm image inspect "$image" --format '{{.Size}}')
    echo "image-check: $image is $((size / 1000000)) MB ($size bytes)"
    echo "image-check: passed in $(( $(now) - t0 )) s"
}

cmd=${1:-}
[ $# -gt 0 ] && shift
case "$cmd" in
build) [ $# -ge 1 ] || { echo "usage: $0 build IMAGE [BASE]" >&2; exit 2; }; build "$@" ;;
check) [ $# -eq 2 ] || { echo "usage: $0 check IMAGE MCF" >&2; exit 2; }; check "$@" ;;
setup) setup ;;
podman) setup; pm "$@" ;;
*) sed -n '2,9p' "$0" >&2; exit 2 ;;
esac
