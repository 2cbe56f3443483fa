#!/usr/bin/env bash
# with-vcan.sh CMD [ARGS...]
#
# Run CMD with a CAN-FD capable `vcan0` (mtu 72) up and exit with CMD's exit
# status.
#
#   * Host path: if this machine already has vcan0, or can create it
#     (`ip link add dev vcan0 type vcan`), CMD runs directly.
#   * VM path: otherwise (kernels without AF_CAN) CMD runs inside a throwaway
#     QEMU VM (TCG, no KVM needed) booting Debian's linux-image-amd64 kernel
#     with a small busybox initramfs built here and cached.  The VM sees the
#     whole host filesystem (host / shared read-only over 9p, under a RAM
#     overlay so writes succeed but are discarded); the current directory
#     (or $WITH_VCAN_OUT) is shared read-write so CMD's outputs come back.
#     CMD runs as root with cwd = $PWD and the caller's environment; its
#     stdout/stderr are streamed to ours; its stdin is /dev/null.  Any host
#     binary, script, build dir or Python venv works unchanged in the VM, but
#     emulated (TCG) code runs ~20x slower than native: the boot takes ~3-5 s
#     on an idle 2-core host, a Python start-up ~1.5 s.  Inside the VM
#     WITH_VCAN_IN_VM=1 is set, so nested calls run CMD directly.
#
# Environment:
#   WITH_VCAN_MODE     auto (default) | host | vm   force one path
#   WITH_VCAN_OUT      ':'-separated host dirs shared read-write with the VM
#                      (created if missing; default: $PWD)
#   WITH_VCAN_TIMEOUT  seconds before a hung VM is killed (default 600)
#   WITH_VCAN_MEM      VM memory (default 1G); WITH_VCAN_SMP: vCPUs (default 2)
#   WITH_VCAN_CPU      QEMU -cpu model (default max)
#   WITH_VCAN_CACHE    cache dir for the initramfs and unpacked kernel
#                      (default ${XDG_CACHE_HOME:-$HOME/.cache}/microdrive-vcan)
#   WITH_VCAN_KERNEL   kernel image (default: newest /boot/vmlinuz-* that has
#                      /lib/modules/<version>)
#   WITH_VCAN_VERBOSE  1: show kernel/init console output on stderr
#
# Exit status: CMD's; 124 if the VM timed out; 125 if the VM could not be
# set up or did not report CMD's status; 2 for usage errors.
#
# Debian packages used: qemu-system-x86 linux-image-amd64 busybox-static
# iproute2 can-utils cpio xz-utils (coreutils, libc-bin).

set -euo pipefail

readonly ME=with-vcan
SCRIPT_DIR=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")" && pwd -P)
readonly SCRIPT_DIR
readonly INIT_SRC=$SCRIPT_DIR/vcan-vm/init
# Bump when the initramfs layout changes, to invalidate old caches.
readonly INITRAMFS_FORMAT=1
# Modules the VM needs (dependencies are added from modules.dep):
# 9p over virtio-pci for the host filesystem, overlay for a writable view,
# and the CAN stack.  can_dev is a dependency of vcan on most kernels.
readonly VM_MODULES="virtio_pci 9pnet_virtio 9p overlay can can_raw vcan"
readonly VM_MODULES_OPTIONAL="can_dev"

log() { printf '%s: %s\n' "$ME" "$*" >&2; }
die() {
    log "error: $*"
    exit 125
}

usage() {
    sed -n '2,/^$/{s/^# \{0,1\}//;p}' "${BASH_SOURCE[0]}" >&2
    exit 2
}

# Microseconds since the epoch, without forking (bash >= 5).
now_us() { local t=${EPOCHREALTIME//[!0-9]/}; printf '%s' "${t:-0}"; }
# Seconds with one decimal between two now_us values.
elapsed() {
    local d=$(($2 - $1))
    printf '%d.%d' $((d / 1000000)) $((d % 1000000 / 100000))
}

# --- host path -------------------------------------------------------------

# Find iproute2's `ip` (not busybox's, which cannot create vcan links).
find_iproute2_ip() {
    local p
    for p in /usr/sbin/ip /sbin/ip /usr/bin/ip /bin/ip; do
        if [[ -x $p ]] && [[ $(readlink -f "$p") != */busybox* ]]; then
            printf '%s' "$p"
            return 0
        fi
    done
    return 1
}

# Succeeds if vcan0 exists (or could be created) with mtu 72 and is up.
# Any failure (no AF_CAN, no vcan module, not root) means "use the VM".
host_vcan_ready() {
    local ip mtu
    ip=$(find_iproute2_ip) || return 1
    if ! "$ip" link show dev vcan0 >/dev/null 2>&1; then
        modprobe -q vcan 2>/dev/null || true
        "$ip" link add dev vcan0 type vcan 2>/dev/null || return 1
    fi
    modprobe -q can_raw 2>/dev/null || true
    mtu=$(cat /sys/class/net/vcan0/mtu 2>/dev/null) || return 1
    if [[ $mtu != 72 ]]; then
        "$ip" link set vcan0 down 2>/dev/null || return 1
        "$ip" link set vcan0 mtu 72 2>/dev/null || return 1
    fi
    "$ip" link set vcan0 up 2>/dev/null || return 1
}

# --- prerequisites ---------------------------------------------------------

# need_cmd COMMAND PACKAGE: die naming the Debian package if COMMAND is absent.
need_cmd() {
    command -v "$1" >/dev/null 2>&1 && return 0
    # sbin may be missing from a non-root PATH.
    [[ -x /usr/sbin/$1 || -x /sbin/$1 ]] && return 0
    die "'$1' not found: install the Debian package '$2' (apt-get install $2)"
}

check_vm_prereqs() {
    need_cmd qemu-system-x86_64 qemu-system-x86
    need_cmd cpio cpio
    need_cmd timeout coreutils
    need_cmd mkfifo coreutils
    need_cmd sha256sum coreutils
    need_cmd ldd libc-bin
    need_cmd cansend can-utils
    need_cmd candump can-utils
    need_cmd cangen can-utils
    IP_BIN=$(find_iproute2_ip) ||
        die "iproute2's 'ip' not found: install the Debian package 'iproute2'"

    BUSYBOX=
    local p
    for p in /bin/busybox /usr/bin/busybox; do
        [[ -x $p ]] && { BUSYBOX=$p; break; }
    done
    [[ -n $BUSYBOX ]] ||
        die "/bin/busybox not found: install the Debian package 'busybox-static'"
    # The initramfs has no libc: busybox must be the static build.
    if ldd "$BUSYBOX" 2>&1 | grep -q '=>'; then
        die "$BUSYBOX is dynamically linked: install 'busybox-static'"
    fi

    select_kernel
}

# Pick the kernel image and its module tree (KERNEL, KVER, MODDIR).
select_kernel() {
    local k v cand=()
    if [[ -n ${WITH_VCAN_KERNEL:-} ]]; then
        cand=("$WITH_VCAN_KERNEL")
    else
        # Newest version first.
        while IFS= read -r k; do cand+=("$k"); done < <(
            compgen -G '/boot/vmlinuz-*' | sort -rV || true)
    fi
    for k in "${cand[@]}"; do
        v=${k##*/vmlinuz-}
        if [[ -f $k && -f /lib/modules/$v/modules.dep ]]; then
            [[ -r $k ]] || die "cannot read $k (permissions): run as root or make it readable"
            KERNEL=$k KVER=$v MODDIR=/lib/modules/$v
            return 0
        fi
    done
    if [[ -n ${WITH_VCAN_KERNEL:-} ]]; then
        die "WITH_VCAN_KERNEL=$WITH_VCAN_KERNEL: need an existing vmlinuz-<version>" \
            "with /lib/modules/<version>/modules.dep"
    fi
    die "no usable /boot/vmlinuz-* with /lib/modules/<version>/modules.dep:" \
        "install the Debian package 'linux-image-amd64'"
}

# --- cached boot artefacts -------------------------------------------------

cache_dir() {
    local d=${WITH_VCAN_CACHE:-${XDG_CACHE_HOME:-${HOME:-/tmp}/.cache}/microdrive-vcan}
    mkdir -p "$d" || die "cannot create cache dir $d (set WITH_VCAN_CACHE)"
    printf '%s' "$d"
}

# Debian's bzImage is xz-compressed; decompressing it under TCG costs ~1 s
# per boot.  If the kernel supports PVH (CONFIG_PVH), QEMU can boot the
# uncompressed ELF vmlinux directly, so extract it once and cache it.
# Prints the image to boot (the vmlinux, or the bzImage as a fallback).
boot_image() {
    local cache=$1 out tmp magic tool off
    if ! grep -q '^CONFIG_PVH=y' "/boot/config-$KVER" 2>/dev/null; then
        printf '%s' "$KERNEL"
        return 0
    fi
    out=$cache/vmlinux-$KVER-$(stat -c '%s-%Y' "$KERNEL")
    if [[ -s $out ]]; then
        touch "$out"
        printf '%s' "$out"
        return 0
    fi
    tmp=$(mktemp "$cache/.vmlinux.XXXXXX")
    # magic (grep -P) and decompressor; the payload is followed by other data,
    # so the decompressor's exit status is ignored and the result checked.
    for magic in 'xz:\xfd7zXZ\x00' 'zstd:\x28\xb5\x2f\xfd' 'gzip:\x1f\x8b\x08'; do
        tool=${magic%%:*}
        command -v "$tool" >/dev/null 2>&1 || continue
        while IFS= read -r off; do
            case $tool in
                xz) tail -c +$((off + 1)) "$KERNEL" | xz -dc --single-stream >"$tmp" 2>/dev/null || true ;;
                zstd) tail -c +$((off + 1)) "$KERNEL" | zstd -dcq >"$tmp" 2>/dev/null || true ;;
                gzip) tail -c +$((off + 1)) "$KERNEL" | gzip -dc >"$tmp" 2>/dev/null || true ;;
            esac
            if [[ $(head -c 4 "$tmp" | od -An -tx1 | tr -d ' \n') == 7f454c46 ]]; then
                chmod 0644 "$tmp"
                mv -f "$tmp" "$out"
                printf '%s' "$out"
                return 0
            fi
        done < <(LC_ALL=C grep -obUaP "${magic#*:}" "$KERNEL" | head -n 3 | cut -d: -f1)
    done
    rm -f "$tmp"
    log "note: could not unpack $KERNEL (xz-utils missing?); booting it compressed (slower)"
    printf '%s' "$KERNEL"
}

# Resolve VM_MODULES plus dependencies to module paths, dependencies first
# (sets MOD_ORDER).  Built-in modules are skipped.
resolve_modules() {
    local -A path_of=() deps_of=() seen=()
    local line p base name
    while IFS= read -r line; do
        p=${line%%:*}
        base=${p##*/}
        base=${base%%.ko*}
        name=${base//-/_}
        path_of[$name]=$p
        deps_of[$p]=${line#*:}
    done <"$MODDIR/modules.dep"
    local -A builtin=()
    if [[ -f $MODDIR/modules.builtin ]]; then
        while IFS= read -r p; do
            base=${p##*/}
            base=${base%%.ko*}
            builtin[${base//-/_}]=1
        done <"$MODDIR/modules.builtin"
    fi

    MOD_ORDER=()
    visit() {
        local m=$1 d
        [[ -n ${seen[$m]:-} ]] && return 0
        seen[$m]=1
        # shellcheck disable=SC2086 # deps are a space-separated list
        for d in ${deps_of[$m]}; do visit "$d"; done
        MOD_ORDER+=("$m")
    }
    for name in $VM_MODULES $VM_MODULES_OPTIONAL; do
        if [[ -n ${path_of[$name]:-} ]]; then
            visit "${path_of[$name]}"
        elif [[ -z ${builtin[$name]:-} && " $VM_MODULES " == *" $name "* ]]; then
            die "kernel module '$name' not found for $KVER (package linux-image-amd64)"
        fi
    done
}

# Copy one module into the initramfs, decompressed (busybox insmod may not
# read .ko.xz/.ko.zst).
stage_module() {
    local src=$MODDIR/$1 dst=$2
    case $src in
        *.ko) cp "$src" "$dst" ;;
        *.ko.xz)
            command -v xz >/dev/null || die "$src is xz-compressed: install 'xz-utils'"
            xz -dc "$src" >"$dst" ;;
        *.ko.zst)
            command -v zstd >/dev/null || die "$src is zstd-compressed: install 'zstd'"
            zstd -dcq "$src" >"$dst" ;;
        *.ko.gz) gzip -dc "$src" >"$dst" ;;
        *) die "unknown module format: $src" ;;
    esac
}

# Build (or reuse) the initramfs: static busybox, the init script and the
# kernel modules.  Everything else (ip, can-utils, CMD, python, ...) comes
# from the host filesystem over 9p.  Cached by a key over all inputs.
initramfs() {
    local cache=$1 key out stage p name
    key=$({
        printf '%s\n' "$INITRAMFS_FORMAT" "$KVER" "$VM_MODULES" "$VM_MODULES_OPTIONAL"
        stat -c '%n %s %Y' "$BUSYBOX" "$MODDIR/modules.dep"
        sha256sum <"$INIT_SRC"
    } | sha256sum | cut -c1-16)
    out=$cache/initramfs-$KVER-$key.cpio
    if [[ -s $out ]]; then
        touch "$out"
        printf '%s' "$out"
        return 0
    fi

    resolve_modules
    stage=$(mktemp -d "$cache/.stage.XXXXXX")
    mkdir -p "$stage"/{bin,dev,proc,sys,run,tmp,etc/with-vcan,lib/modules}
    cp "$BUSYBOX" "$stage/bin/busybox"
    ln -s busybox "$stage/bin/sh"
    install -m 0755 "$INIT_SRC" "$stage/init"
    : >"$stage/etc/with-vcan/modules"
    for p in "${MOD_ORDER[@]}"; do
        name=${p##*/}
        name=${name%%.ko*}
        stage_module "$p" "$stage/lib/modules/$name.ko"
        printf '%s\n' "$name" >>"$stage/etc/with-vcan/modules"
    done
    (cd "$stage" && find . -mindepth 1 | LC_ALL=C sort |
        cpio -o -H newc -R 0:0 --quiet) >"$stage.cpio"
    mv -f "$stage.cpio" "$out"
    rm -rf "$stage"
    # Drop artefacts of other inputs not used for a week.
    find "$cache" -maxdepth 1 \( -name 'initramfs-*' -o -name 'vmlinux-*' \) \
        -mtime +7 -delete 2>/dev/null || true
    printf '%s' "$out"
}

# --- VM path ---------------------------------------------------------------

# Escape a value for a QEMU option list (',' must be doubled).
qemu_esc() { printf '%s' "${1//,/,,}"; }

# Canonical, deduplicated read-write dirs, parents first (sets RW_DIRS).
collect_rw_dirs() {
    local spec=${WITH_VCAN_OUT:-$PWD} d abs
    local -a list=()
    IFS=: read -r -a list <<<"$spec"
    RW_DIRS=()
    for d in "${list[@]}"; do
        [[ -n $d ]] || continue
        mkdir -p -- "$d" || die "cannot create WITH_VCAN_OUT dir $d"
        abs=$(cd -- "$d" && pwd -P) || die "cannot resolve $d"
        [[ $abs != / ]] || die "refusing to share / read-write (WITH_VCAN_OUT)"
        [[ $abs != *$'\n'* ]] || die "newline in path: $d"
        RW_DIRS+=("$abs")
    done
    if ((${#RW_DIRS[@]})); then
        mapfile -t RW_DIRS < <(printf '%s\n' "${RW_DIRS[@]}" | LC_ALL=C sort -u)
    fi
}

# job.sh: replays our environment, cwd and umask, then execs CMD.
write_job() {
    local job=$1 name
    shift
    {
        printf '#!/bin/bash\n# generated by %s\n' "$ME"
        while IFS= read -r name; do
            case $name in
                PWD | OLDPWD | SHLVL | _ | BASHOPTS | SHELLOPTS | BASH_*) continue ;;
            esac
            printf 'export %s=%q\n' "$name" "${!name-}"
        done < <(compgen -e)
        printf 'export WITH_VCAN_IN_VM=1\n'
        printf 'umask %s\n' "$(umask)"
        printf 'cd -- %q || exit 125\n' "$PWD"
        printf 'set --'
        printf ' %q' "$@"
        printf '\nexec "$@"\n'
    } >"$job/job.sh"
    {
        printf 'WV_IP=%q\n' "$IP_BIN"
        printf 'WV_NRW=%d\n' "${#RW_DIRS[@]}"
    } >"$job/vm.conf"
    if ((${#RW_DIRS[@]})); then
        printf '%s\n' "${RW_DIRS[@]}" >"$job/rw.list"
    else
        : >"$job/rw.list"
    fi
}

# Reads the VM console (stdin): logs it, announces the boot, records the
# exit marker in $job/status.
console_reader() {
    local job=$1 t0=$2 line rc
    while IFS= read -r line || [[ -n $line ]]; do
        line=${line%$'\r'}
        printf '%s\n' "$line" >>"$job/console.log"
        case $line in
            *WITH_VCAN_BOOTED*)
                log "VM path (qemu tcg, kernel $KVER): booted in $(elapsed "$t0" "$(now_us)") s" \
                    "(guest ${line##*uptime=} s)"
                ;;
            *WITH_VCAN_ERROR:*)
                log "VM setup failed: ${line#*WITH_VCAN_ERROR: }"
                ;;
            *WITH_VCAN_EXIT=*)
                rc=${line##*WITH_VCAN_EXIT=}
                rc=${rc%%[!0-9]*}
                [[ -n $rc ]] && printf '%s\n' "$rc" >"$job/status"
                ;;
            *)
                [[ ${WITH_VCAN_VERBOSE:-0} == 1 ]] && printf '[vm] %s\n' "$line" >&2
                ;;
        esac
    done
}

QEMU_PID=''
READER_PIDS=()
JOB_DIR=''

# EXIT trap of the VM path: stop QEMU and the readers, remove the job dir.
# shellcheck disable=SC2317 # invoked by trap
cleanup() {
    local p
    set +e
    [[ -n $QEMU_PID ]] && kill "$QEMU_PID" 2>/dev/null
    for p in "${READER_PIDS[@]}"; do kill "$p" 2>/dev/null; done
    [[ -n $JOB_DIR ]] && rm -rf -- "$JOB_DIR"
    return 0
}

# After QEMU is gone: a reader still blocked opening its FIFO (QEMU died
# before opening it) gets a writer that closes at once, i.e. EOF.
release_readers() {
    local f fd i p alive
    for ((i = 0; i < 50; i++)); do
        alive=0
        for p in "${READER_PIDS[@]}"; do kill -0 "$p" 2>/dev/null && alive=1; done
        ((alive)) || break
        for f in con out err; do
            exec {fd}<>"$JOB_DIR/$f.out" && exec {fd}>&-
        done
        sleep 0.1
    done
    for p in "${READER_PIDS[@]}"; do kill "$p" 2>/dev/null || true; done
    wait "${READER_PIDS[@]}" 2>/dev/null || true
    READER_PIDS=()
}

show_console_tail() {
    [[ -s $JOB_DIR/console.log ]] || { log "(no console output)"; return 0; }
    log "last console lines (WITH_VCAN_VERBOSE=1 shows all):"
    tail -n 25 "$JOB_DIR/console.log" | sed 's/^/  | /' >&2
}

run_in_vm() {
    check_vm_prereqs
    local cache kernel_img initrd t0 t_end qrc=0 rc i timeout_s smp
    cache=$(cache_dir)
    kernel_img=$(boot_image "$cache")
    initrd=$(initramfs "$cache")
    collect_rw_dirs

    JOB_DIR=$(mktemp -d "${TMPDIR:-/tmp}/with-vcan.XXXXXX")
    # The job path travels on the kernel command line: no whitespace.
    if [[ $JOB_DIR == *[[:space:]]* ]]; then
        rm -rf -- "$JOB_DIR"
        JOB_DIR=$(mktemp -d /tmp/with-vcan.XXXXXX)
    fi
    trap cleanup EXIT
    trap 'exit 130' INT
    trap 'exit 143' TERM
    write_job "$JOB_DIR" "$@"

    local cmdline="console=ttyS0 panic=-1 rdinit=/init"
    # Boot-time savers under TCG: skip crypto self-tests and mitigations.
    cmdline+=" cryptomgr.notests mitigations=off nokaslr"
    if [[ ${WITH_VCAN_VERBOSE:-0} == 1 ]]; then
        cmdline+=" loglevel=7"
    else
        cmdline+=" quiet loglevel=0"
    fi
    cmdline+=" wv.job=$JOB_DIR"

    smp=${WITH_VCAN_SMP:-2}
    local -a qemu=(qemu-system-x86_64 -accel tcg -machine pc -cpu "${WITH_VCAN_CPU:-max}"
        -smp "$smp" -m "${WITH_VCAN_MEM:-1G}"
        -nodefaults -no-user-config -display none -no-reboot -net none
        -kernel "$kernel_img" -initrd "$initrd" -append "$cmdline")
    # ttyS0 console, ttyS1 CMD stdout, ttyS2 CMD stderr, each to a FIFO pair
    # (QEMU writes <name>.out, reads <name>.in).
    for i in con out err; do
        mkfifo "$JOB_DIR/$i.in" "$JOB_DIR/$i.out"
        qemu+=(-chardev "pipe,id=$i,path=$(qemu_esc "$JOB_DIR/$i")" -serial "chardev:$i")
    done
    # shellcheck disable=SC2054 # commas belong to QEMU's option syntax
    qemu+=(-fsdev "local,id=hostroot,path=/,security_model=none,readonly=on,multidevs=remap"
        -device virtio-9p-pci,fsdev=hostroot,mount_tag=hostroot)
    for i in "${!RW_DIRS[@]}"; do
        qemu+=(-fsdev "local,id=rw$i,path=$(qemu_esc "${RW_DIRS[$i]}"),security_model=none,multidevs=remap"
            -device "virtio-9p-pci,fsdev=rw$i,mount_tag=rw$i")
    done

    t0=$(now_us)
    cat "$JOB_DIR/out.out" &
    READER_PIDS+=($!)
    cat "$JOB_DIR/err.out" >&2 &
    READER_PIDS+=($!)
    console_reader "$JOB_DIR" "$t0" <"$JOB_DIR/con.out" &
    READER_PIDS+=($!)

    timeout_s=${WITH_VCAN_TIMEOUT:-600}
    timeout --kill-after=10 "$timeout_s" "${qemu[@]}" </dev/null &
    QEMU_PID=$!
    wait "$QEMU_PID" || qrc=$?
    QEMU_PID=
    release_readers
    t_end=$(now_us)

    if [[ -s $JOB_DIR/status ]]; then
        rc=$(<"$JOB_DIR/status")
        ((rc == 125)) && grep -q 'WITH_VCAN_ERROR' "$JOB_DIR/console.log" && show_console_tail
        log "VM path: CMD exited $rc; total $(elapsed "$t0" "$t_end") s"
        return "$rc"
    fi
    if ((qrc == 124)); then
        log "error: VM killed after ${timeout_s} s (WITH_VCAN_TIMEOUT)"
        show_console_tail
        return 124
    fi
    log "error: VM ended (qemu status $qrc) without reporting CMD's exit status"
    show_console_tail
    return 125
}

main() {
    [[ ${1:-} == -- ]] && shift
    case ${1:-} in
        '' | -h | --help) usage ;;
    esac
    local mode=${WITH_VCAN_MODE:-auto} t0
    # Inside our own VM vcan0 exists: never nest another VM.
    [[ ${WITH_VCAN_IN_VM:-} == 1 ]] && mode=host
    case $mode in
        auto | host | vm) ;;
        *) die "WITH_VCAN_MODE must be auto, host or vm (got '$mode')" ;;
    esac

    if [[ $mode != vm ]]; then
        t0=$(now_us)
        if host_vcan_ready; then
            log "host path: vcan0 (mtu 72) ready in $(elapsed "$t0" "$(now_us)") s, running CMD directly"
            exec "$@"
        fi
        [[ $mode == host ]] && die "WITH_VCAN_MODE=host but vcan0 is not available here"
    fi
    local rc=0
    run_in_vm "$@" || rc=$?
    exit "$rc"
}

main "$@"
