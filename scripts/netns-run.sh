#!/bin/sh
# Runs CMD... in a private, throwaway network namespace whose only interface
# is loopback (up, with a multicast route), so a test's packets cannot reach
# any other machine, and parallel tests cannot hear each other.
#
#   scripts/netns-run.sh [--unprivileged] CMD [ARGS...]
#
# --unprivileged: always a new user namespace too (unshare -rn), even for
# root: the command then has no CAP_NET_ADMIN in the initial namespace, so
# the kernel refuses SO_RCVBUFFORCE and caps socket buffers at
# net.core.rmem_max, as for any ordinary user.
#
# Needs unshare(1) from util-linux and ip(8) from iproute2, and the right to
# create user + network namespaces (root, or unprivileged user namespaces).
# Exit status: CMD's, or 125 if the namespace could not be set up.
set -eu
unprivileged=0
if [ "${1:-}" = "--unprivileged" ]; then
    unprivileged=1
    shift
fi
if [ "$#" -eq 0 ]; then
    echo "usage: $0 [--unprivileged] CMD [ARGS...]" >&2
    exit 2
fi
for tool in unshare ip; do
    if ! command -v "$tool" >/dev/null 2>&1; then
        echo "netns-run: '$tool' not found (install util-linux / iproute2)" >&2
        exit 125
    fi
done
# Real root keeps its capabilities with a plain -n (no new user namespace):
# the kernel honours SO_RCVBUFFORCE only for CAP_NET_ADMIN in the initial
# user namespace, and the bus endpoints need large receive buffers to ride
# out a recording's frame burst (docs/bus.md). Anyone else gets -rn.
ns_flags=-rn
if [ "$unprivileged" -eq 0 ] && [ "$(id -u)" -eq 0 ] && unshare -n true 2>/dev/null; then
    ns_flags=-n
fi
if ! why=$(unshare $ns_flags true 2>&1); then
    echo "netns-run: cannot create a network namespace (unshare $ns_flags: $why)" >&2
    if [ "$ns_flags" = "-rn" ]; then
        echo "netns-run: a user namespace needs root or unprivileged user namespaces" >&2
        echo "netns-run: (kernel.unprivileged_userns_clone=1; kernel.apparmor_restrict_unprivileged_userns=0" >&2
        echo "netns-run: on Ubuntu >= 23.10), and the kernel refuses one to any process in a chroot:" >&2
        echo "netns-run: run the tests on the host, in a container or a VM instead" >&2
    fi
    exit 125
fi
# -r maps the caller to root inside, so this also works for a non-root user
# where user namespaces are allowed; -n gives the new network namespace.
exec unshare $ns_flags sh -c '
    ip link set lo up || { echo "netns-run: cannot bring lo up" >&2; exit 125; }
    ip route add 224.0.0.0/4 dev lo || { echo "netns-run: cannot add multicast route" >&2; exit 125; }
    exec "$@"' netns-run "$@"
