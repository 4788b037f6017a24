#!/usr/bin/env bash
# Installs everything the ARM cross builds, the qemu-user test runs and the
# vivid VM test need, from Debian packages and rustup targets only.
# Idempotent: a second run installs nothing and takes about a second.
#
#   cross/install.sh          # everything
#   cross/install.sh --no-vm  # skip the VM tests' packages: qemu-system-arm,
#                             # busybox-static, kmod, cpio, netcat-openbsd and, for
#                             # deploy-test.sh, debootstrap, e2fsprogs, qemu-utils,
#                             # openssh-client
set -euo pipefail

want_vm=1
[[ "${1:-}" == "--no-vm" ]] && want_vm=0

SUDO=""
if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive

# Debian packages -> the command each one provides (to skip apt when present).
pkgs=(
    gcc-aarch64-linux-gnu:aarch64-linux-gnu-gcc
    gcc-arm-linux-gnueabihf:arm-linux-gnueabihf-gcc
    libc6-dev-arm64-cross:/usr/aarch64-linux-gnu/include/stdio.h
    libc6-dev-armhf-cross:/usr/arm-linux-gnueabihf/include/stdio.h
    qemu-user-static:qemu-aarch64-static
    clang:clang
    libclang-dev:/usr/lib/llvm-14/lib/libclang.so
    time:/usr/bin/time
)
if [[ $want_vm -eq 1 ]]; then
    pkgs+=(busybox-static:/bin/busybox kmod:depmod cpio:cpio netcat-openbsd:nc)
    # cross/deploy-test.sh: a Debian arm64 root file system, its disk image, ssh to it.
    pkgs+=(debootstrap:debootstrap e2fsprogs:mke2fs qemu-utils:qemu-img openssh-client:ssh)
fi

have() {
    if [[ "$1" == /* ]]; then [[ -e "$1" ]]; else command -v "$1" >/dev/null 2>&1; fi
}

missing=()
for p in "${pkgs[@]}"; do
    name=${p%%:*} probe=${p#*:}
    # busybox-static puts /bin/busybox; the dynamic busybox does too, so check the package.
    if [[ $name == busybox-static ]]; then
        dpkg-query -W -f='${Status}' busybox-static 2>/dev/null | grep -q 'ok installed' || missing+=("$name")
        continue
    fi
    have "$probe" || missing+=("$name")
done

updated=0
apt_update() {
    if [[ $updated -eq 0 ]]; then $SUDO apt-get update -qq; updated=1; fi
}

if [[ ${#missing[@]} -gt 0 ]]; then
    echo "cross/install.sh: apt-get install ${missing[*]}"
    apt_update
    $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# qemu-system-aarch64 for the vivid VM test. On images that carry a newer
# qemu-utils from bookworm-backports, the bookworm qemu-system-arm would
# remove it: try without removals, else take the matching backports build.
if [[ $want_vm -eq 1 ]] && ! have qemu-system-aarch64; then
    apt_update
    if ! $SUDO apt-get install -y -qq --no-remove --no-install-recommends qemu-system-arm; then
        . /etc/os-release
        suite="${VERSION_CODENAME}-backports"
        list=/etc/apt/sources.list.d/stature-backports.sources
        if ! grep -rqs "$suite" /etc/apt/sources.list /etc/apt/sources.list.d/; then
            echo "cross/install.sh: adding $suite for qemu-system-arm"
            printf 'Types: deb\nURIs: http://deb.debian.org/debian\nSuites: %s\nComponents: main\nSigned-By: /usr/share/keyrings/debian-archive-keyring.gpg\n' \
                "$suite" | $SUDO tee "$list" >/dev/null
            $SUDO apt-get update -qq
        fi
        $SUDO apt-get install -y -qq --no-remove --no-install-recommends -t "$suite" qemu-system-arm
    fi
fi

# Rust targets (rustup is the project's toolchain manager).
targets=(aarch64-unknown-linux-gnu armv7-unknown-linux-gnueabihf aarch64-unknown-linux-musl)
installed=$(rustup target list --installed)
for t in "${targets[@]}"; do
    grep -qx "$t" <<<"$installed" || rustup target add "$t"
done

# binfmt_misc entries so that an ARM test binary running under qemu-user can
# spawn the ARM `stature` binary (integration tests do). Debian's
# qemu-user-binfmt ships the entries; without systemd-binfmt running (CI
# containers), register them by hand. QEMU_LD_PREFIX (set by the cargo
# runner) gives the children their sysroot.
register_binfmt() {
    local name=$1 conf=/usr/lib/binfmt.d/qemu-$1.conf
    local fs=/proc/sys/fs/binfmt_misc
    [[ -e $fs/qemu-$name ]] && return 0
    if [[ ! -e $fs/register ]]; then
        $SUDO mount -t binfmt_misc binfmt_misc "$fs" 2>/dev/null || true
    fi
    if [[ -e $fs/register && -f $conf ]]; then
        grep -v '^#' "$conf" | $SUDO tee "$fs/register" >/dev/null || true
    fi
    [[ -e $fs/qemu-$name ]] || echo "cross/install.sh: warning: no binfmt_misc entry for $name; tests that spawn the binary will fail under qemu-user" >&2
}
register_binfmt aarch64
register_binfmt arm

echo "cross/install.sh: ok ($(aarch64-linux-gnu-gcc -dumpversion) cross gcc, $(qemu-aarch64-static --version | head -1)$(
    [[ $want_vm -eq 1 ]] && echo ", $(qemu-system-aarch64 --version | head -1)"))"
