#!/usr/bin/env bash
# The README's "Deploying to a board" (cross/README.md), followed step by
# step on a real Debian arm64 system with systemd, as a new user would:
# the board is qemu-system-aarch64 (-M virt -cpu cortex-a57, TCG) booting a
# Debian bookworm root file system made with debootstrap from Debian's
# mirror (second stage under qemu-user through binfmt_misc), the Debian
# arm64 kernel package and its own initramfs, systemd as init, sshd, a
# sudo user `pi` (like Raspberry Pi OS), and the kernel's vivid driver as
# the camera (loaded at boot by modules-load.d, like a UVC webcam is).
#
# The commands run are the README's own shell blocks, read from
# cross/README.md at run time (so the test follows the text, not a copy):
# only the board's address (ssh config: camera.local is the VM's forwarded
# sshd) and the workstation's address (192.168.1.20 -> 10.0.2.2, the host as
# qemu user networking shows it) are the VM's. Then it checks what the
# README and board/stature.service promise:
#   - reports arrive on the workstation's UDP listener (the README's nc
#     command), hello at the rpi4 profile's 1280x720 YUYV, then status;
#   - the unit is enabled and active; the process runs as user `stature`
#     with groups video and dialout; under ProtectSystem=strict the system
#     is read-only in the service's mount namespace and /var/lib/stature
#     (StateDirectory) is writable; the profile's caps are in force;
#   - a restart writes the calibration state to /var/lib/stature (owned by
#     stature) and the next start resumes from it;
#   - SIGKILL -> Restart=on-failure starts it again and the workstation
#     keeps receiving (a new source port);
#   - unplugging the camera (vivid unbound through sysfs) -> `reconnecting`
#     status records, replugging -> streaming again, under the unit's
#     DevicePolicy;
#   - no camera at start: exit 3, retried for as long as it takes (90 s
#     here), then streams once the camera is there;
#   - after a reboot the service is up again (enabled) and resumes;
#   - the README's Pi Zero 2 row as an upgrade ("run the installer again"):
#     the static musl build with rpi-zero2.toml, its 640x480 mode, its UART
#     sink (/dev/serial0: group dialout, DeviceAllow char-ttyAMA) and caps.
#
#   cross/deploy-test.sh                # builds the image once (cached), boots a fresh copy
#   DEPLOY_REBUILD=1 cross/deploy-test.sh   # rebuild the cached Debian image
#   DEPLOY_KEEP=1 cross/deploy-test.sh  # leave the VM running at the end (ssh -F .../ssh_config camera.local)
#
# Needs root (debootstrap, chroot) and cross/install.sh (qemu-user-static
# with binfmt_misc, qemu-system-aarch64, debootstrap). Takes minutes (see
# cross/README.md): on demand, not in every CI run. Cache:
# $CARGO_TARGET_DIR/cross-cache/deploy (about 1 GB; DEPLOY_CACHE overrides).
set -euo pipefail

here=$(cd "$(dirname "$0")" && pwd)
repo=$(dirname "$here")
target_dir=${CARGO_TARGET_DIR:-$repo/target}
cache=${DEPLOY_CACHE:-$target_dir/cross-cache/deploy}
suite=${DEPLOY_SUITE:-bookworm}
mirror=${DEPLOY_MIRROR:-http://deb.debian.org/debian}
# Bump when the image recipe below changes (forces a rebuild of the cache).
image_version="2 $suite"
mkdir -p "$cache"
cache=$(cd "$cache" && pwd)
t_start=$(date +%s)

die() { echo "deploy-test: FAIL: $*" >&2; exit 1; }
say() { echo "deploy-test: [$(($(date +%s) - t_start)) s] $*"; }
SUDO=""
[[ $(id -u) -eq 0 ]] || SUDO=sudo

for tool in debootstrap qemu-system-aarch64 qemu-img mke2fs ssh scp ssh-keygen nc python3; do
    command -v $tool >/dev/null || die "$tool missing: run cross/install.sh"
done
[[ -e /proc/sys/fs/binfmt_misc/qemu-aarch64 ]] ||
    die "no binfmt_misc entry for aarch64 (cross/install.sh registers it): debootstrap's second stage needs it"

# --- 1. The board image (cached): Debian arm64 with systemd.
img=$cache/base.img
key=$cache/id_ed25519
build_image() {
    local root=$cache/root
    say "building the Debian $suite arm64 image (debootstrap from $mirror)"
    cleanup_mounts() {
        for m in dev/pts dev proc sys; do
            mountpoint -q "$root/$m" 2>/dev/null && $SUDO umount -l "$root/$m" || true
        done
    }
    trap cleanup_mounts EXIT
    $SUDO rm -rf "$root" "$img"
    [[ -f $key ]] || ssh-keygen -q -t ed25519 -N "" -C "deploy-test" -f "$key"
    local pkgs=systemd,systemd-sysv,udev,kmod,dbus,openssh-server,sudo,iproute2,procps,initramfs-tools,linux-image-arm64
    $SUDO debootstrap --foreign --arch=arm64 --variant=minbase --include="$pkgs" \
        "$suite" "$root" "$mirror" >"$cache/debootstrap-1.log" 2>&1 ||
        { tail -20 "$cache/debootstrap-1.log"; die "debootstrap (first stage) failed"; }
    # Before the kernel package is configured: an initramfs with the few
    # modules the virt board needs to mount its root (virtio-mmio disk,
    # ext4) instead of MODULES=most, which under qemu-user takes 20 minutes.
    $SUDO mkdir -p "$root/etc/initramfs-tools/conf.d" "$root/etc/initramfs-tools/hooks"
    printf 'MODULES=list\nCOMPRESS=gzip\n' | $SUDO tee "$root/etc/initramfs-tools/conf.d/virt-board.conf" >/dev/null
    $SUDO tee "$root/etc/initramfs-tools/hooks/virt-board" >/dev/null <<'EOF'
#!/bin/sh
# The qemu virt board's root disk: virtio-mmio, virtio-blk, ext4.
[ "$1" = prereqs ] && exit 0
. /usr/share/initramfs-tools/hook-functions
force_load virtio_mmio
force_load virtio_blk
force_load ext4
# The console is a virtio console (hvc0): the UART stays free for a sink.
force_load virtio_console
EOF
    $SUDO chmod 0755 "$root/etc/initramfs-tools/hooks/virt-board"
    $SUDO chroot "$root" /debootstrap/debootstrap --second-stage >"$cache/debootstrap-2.log" 2>&1 ||
        { tail -20 "$cache/debootstrap-2.log"; die "debootstrap (second stage, under qemu-user) failed"; }
    say "debootstrap done; configuring the board"
    # What a board image comes with: a host name, the root file system,
    # DHCP on the wired port, a sudo user reachable over ssh, the camera.
    echo camera | $SUDO tee "$root/etc/hostname" >/dev/null
    printf '127.0.0.1 localhost\n127.0.1.1 camera\n' | $SUDO tee "$root/etc/hosts" >/dev/null
    echo '/dev/vda / ext4 defaults 0 1' | $SUDO tee "$root/etc/fstab" >/dev/null
    printf '[Match]\nName=e*\n\n[Network]\nDHCP=yes\n' | $SUDO tee "$root/etc/systemd/network/20-wired.network" >/dev/null
    $SUDO chroot "$root" systemctl enable systemd-networkd.service >/dev/null 2>&1
    $SUDO chroot "$root" useradd -m -s /bin/bash -G sudo pi
    # Raspberry Pi OS's default: the first user runs sudo without a password.
    echo 'pi ALL=(ALL) NOPASSWD: ALL' | $SUDO tee "$root/etc/sudoers.d/010_pi-nopasswd" >/dev/null
    $SUDO chmod 0440 "$root/etc/sudoers.d/010_pi-nopasswd"
    $SUDO install -d -m 0700 -o 1000 -g 1000 "$root/home/pi/.ssh"
    $SUDO install -m 0600 -o 1000 -g 1000 "$key.pub" "$root/home/pi/.ssh/authorized_keys"
    # The camera: vivid as a webcam-type capture device, loaded at boot.
    echo vivid | $SUDO tee "$root/etc/modules-load.d/camera.conf" >/dev/null
    echo 'options vivid n_devs=1 node_types=0x1' | $SUDO tee "$root/etc/modprobe.d/camera.conf" >/dev/null
    # Raspberry Pi OS names the GPIO UART /dev/serial0 (the Zero 2 profile's
    # sink); here it is the virt board's PL011. Its console is off, as the
    # profile asks: the kernel console is hvc0.
    echo 'KERNEL=="ttyAMA0", SYMLINK+="serial0"' | $SUDO tee "$root/etc/udev/rules.d/99-serial0.rules" >/dev/null
    $SUDO rm -f "$root"/var/cache/apt/archives/*.deb
    cleanup_mounts
    trap - EXIT
    local kver
    kver=$(ls "$root/lib/modules" | head -1)
    [[ -f $root/boot/initrd.img-$kver ]] || die "the kernel package made no initramfs (see $cache/debootstrap-2.log)"
    cp "$root/boot/vmlinuz-$kver" "$cache/vmlinuz"
    cp "$root/boot/initrd.img-$kver" "$cache/initrd.img"
    $SUDO mke2fs -q -t ext4 -L root -d "$root" "$img" 2G
    $SUDO rm -rf "$root"
    echo "$image_version" >"$cache/base.stamp"
    say "image ready: Debian $suite arm64, kernel $kver, $(du -h --apparent-size "$img" | cut -f1) sparse"
}
if [[ -n "${DEPLOY_REBUILD:-}" || ! -f $img || ! -f $cache/base.stamp ||
    $(cat "$cache/base.stamp") != "$image_version" ]]; then
    build_image
fi

# --- 2. A fresh board for every run: a copy-on-write overlay of the image.
run=$cache/run
rm -rf "$run"
mkdir -p "$run"
qemu-img create -q -f qcow2 -b "$img" -F raw "$run/board.qcow2"
free_port() { # PROTO -> a free local port
    python3 -c "import socket,sys; s=socket.socket(socket.AF_INET, socket.SOCK_DGRAM if sys.argv[1]=='udp' else socket.SOCK_STREAM); s.bind(('127.0.0.1', 0)); print(s.getsockname()[1])" "$1"
}
port_free() { # PROTO PORT
    python3 -c "import socket,sys; s=socket.socket(socket.AF_INET, socket.SOCK_DGRAM if sys.argv[1]=='udp' else socket.SOCK_STREAM); s.bind(('0.0.0.0', int(sys.argv[2])))" "$1" "$2" 2>/dev/null
}
ssh_port=$(free_port tcp)
# The README's port (9000) unless another program on this machine has it.
udp_port=9000
port_free udp $udp_port || udp_port=$(free_port udp)
cat >"$run/ssh_config" <<EOF
Host camera.local
    HostName 127.0.0.1
    Port $ssh_port
    IdentityFile $key
    IdentitiesOnly yes
    StrictHostKeyChecking no
    UserKnownHostsFile /dev/null
    LogLevel ERROR
    ConnectTimeout 20
    ServerAliveInterval 10
EOF
# Everything below that says ssh or scp (the README's commands too) goes to the VM.
ssh() { command ssh -F "$run/ssh_config" "$@"; }
scp() { command scp -F "$run/ssh_config" "$@"; }
# ssh exits 255 for its own failures (a TCG guest under load can miss the
# banner timeout): those are retried, the command's own status is not.
on_board() {
    local try rc
    for try in 1 2 3 4 5; do
        rc=0
        ssh pi@camera.local "$@" || rc=$?
        [[ $rc -eq 255 ]] || return $rc
        sleep 3
    done
    return $rc
}

boot() {
    qemu-system-aarch64 -M virt -cpu cortex-a57 -smp 2 -m 1024 -accel tcg \
        -nographic -kernel "$cache/vmlinuz" -initrd "$cache/initrd.img" \
        -append "root=/dev/vda rw console=hvc0 quiet" \
        -drive if=none,id=disk,file="$run/board.qcow2",format=qcow2 \
        -device virtio-blk-device,drive=disk \
        -netdev user,id=n0,hostfwd=tcp:127.0.0.1:$ssh_port-:22 \
        -device virtio-net-device,netdev=n0 \
        -device virtio-rng-device \
        -device virtio-serial-device -chardev file,id=con,path="$run/console.log" \
        -device virtconsole,chardev=con \
        -serial file:"$run/uart.log" -monitor none \
        </dev/null >>"$run/qemu.log" 2>&1 &
    qemu_pid=$!
}
wait_ssh() { # SECONDS
    local deadline=$(($(date +%s) + $1))
    until ssh pi@camera.local true 2>/dev/null; do
        kill -0 $qemu_pid 2>/dev/null || { tail -30 "$run/console.log"; die "the VM stopped while booting"; }
        (($(date +%s) < deadline)) || { tail -30 "$run/console.log"; die "no ssh on the board after $1 s"; }
        sleep 3
    done
}
nc_pid=""
cleanup() {
    [[ -n $nc_pid ]] && kill "$nc_pid" 2>/dev/null
    if [[ -z "${DEPLOY_KEEP:-}" && -n "${qemu_pid:-}" ]]; then kill "$qemu_pid" 2>/dev/null; fi
    true
}
trap cleanup EXIT

say "booting a fresh board (ssh on 127.0.0.1:$ssh_port, reports to UDP $udp_port)"
t_boot=$(date +%s)
boot
wait_ssh 600
say "board up after $(($(date +%s) - t_boot)) s: $(on_board 'uname -srm; systemctl is-system-running' | tr '\n' ' ')"

# --- 3. The README's steps, as written.
readme=$repo/cross/README.md
blocks=$run/readme-blocks
nblocks=$(python3 - "$readme" "$blocks" <<'EOF'
import re, sys
text = open(sys.argv[1]).read()
m = re.search(r"^## Deploying to a board\n(.*?)(?=^## )", text, re.S | re.M)
if not m:
    sys.exit("cross/README.md has no '## Deploying to a board' section")
blocks = re.findall(r"```sh\n(.*?)```", m.group(1), re.S)
for i, b in enumerate(blocks, 1):
    open(f"{sys.argv[2]}.{i}", "w").write(b)
print(len(blocks))
EOF
)
[[ $nblocks -ge 4 ]] || die "expected the README's four shell steps (install, copy, install on the board, read), found $nblocks"
# The README's workstation (192.168.1.20) is the host as the VM sees it.
adapt() { sed -e "s/192\.168\.1\.20/10.0.2.2/g" -e "s/\b9000\b/$udp_port/g" "$1"; }
echo "--- README step 1 (toolchains)"; cat "$blocks.1"
# Step 2 is the build table: the Pi 4 row (the profile the steps below copy).
build_cmd=$(sed -n 's/^| Raspberry Pi 4.*| `\(cross\/build\.sh [^`]*\)` |$/\1/p' "$readme")
[[ -n $build_cmd ]] || die "no Raspberry Pi 4 build command in the README's table"
echo "--- README step 2 (build): $build_cmd"
(cd "$repo" && bash "$blocks.1" >"$run/step1.log" 2>&1 && $build_cmd >"$run/step2.log" 2>&1) ||
    { tail -20 "$run"/step*.log; die "README steps 1-2 failed on the workstation"; }
# Step 5 first: the listener must be up before the service starts.
listen=$(adapt "$blocks.4" | sed -n 's/^\(nc [^#]*\).*/\1/p' | head -1)
[[ -n $listen ]] || die "no nc command in the README's step 5"
echo "--- README step 5 (workstation listener): $listen"
(cd "$run" && exec $listen </dev/null >"$run/udp.jsonl" 2>"$run/nc.err") &
nc_pid=$!
# Steps 3 and 4 in one shell, as in one terminal (step 4 uses step 3's $B).
echo "--- README steps 3 and 4 (from $repo)"
adapt "$blocks.2" >"$run/steps34.sh"
adapt "$blocks.3" >>"$run/steps34.sh"
sed 's/^/    $ /' "$run/steps34.sh"
(cd "$repo" && export -f ssh scp && export run && bash -eo pipefail "$run/steps34.sh") \
    >"$run/steps34.log" 2>&1 || { cat "$run/steps34.log"; die "README steps 3-4 failed"; }
sed 's/^/    | /' "$run/steps34.log"

# --- 4. What the README and the unit promise.
failures=()
check() { # WHAT CMD... : passes when CMD succeeds
    local what=$1
    shift
    if "$@" >/dev/null 2>&1; then echo "  ok   $what"; else echo "  FAIL $what"; failures+=("$what"); fi
}
records() { python3 "$here/deploy_check.py" "$run/udp.jsonl" "$@"; }
wait_for() { # SECONDS CMD... : polls until CMD succeeds
    local deadline=$(($(date +%s) + $1))
    shift
    until "$@" >/dev/null 2>&1; do
        (($(date +%s) < deadline)) || return 1
        sleep 2
    done
}
unit() { on_board systemctl show -p "$1" --value stature; }
is() { [[ $1 == "$2" ]]; }
# In the service's own mount namespace, as root: writing PATH must fail
# with EROFS (ProtectSystem=strict binds it read-only even for root).
read_only_to_service() { # PID PATH
    local err
    err=$(on_board "sudo nsenter -t $1 -m touch $2/.probe" 2>&1) && return 1
    [[ $err == *"Read-only file system"* ]]
}
writable_to_service_user() { # PID DIR
    on_board "sudo nsenter -t $1 -m -S \$(id -u stature) -G \$(id -g stature) sh -c 'touch $2/.probe && rm $2/.probe'"
}
journal_has() { on_board "sudo journalctl -u stature -b --no-pager | grep -q '$1'"; }

echo "--- checks"
check "the workstation receives hello over UDP" wait_for 180 records count hello 1
check "hello: the rpi4 profile's mode ($(records last hello))" records hello-mode 1280 720 YUYV
check "status records follow" wait_for 180 records count status 1
echo "       last status: $(records last status)"
check "unit enabled" is "$(on_board systemctl is-enabled stature)" enabled
check "unit active" is "$(on_board systemctl is-active stature)" active
pid=$(unit MainPID)
ps_line=$(on_board ps -o user=,group=,supgrp= -p "$pid" | xargs)
check "process runs as user stature, group stature ($ps_line)" eval '[[ $ps_line == "stature stature "* ]]'
check "... with supplementary groups video and dialout" eval '[[ $ps_line == *video* && $ps_line == *dialout* ]]'
check "ProtectSystem=strict: /usr is read-only to the service" read_only_to_service "$pid" /usr/local/bin
check "ProtectSystem=strict: /etc is read-only to the service" read_only_to_service "$pid" /etc/stature
check "StateDirectory: /var/lib/stature is writable to the service user" writable_to_service_user "$pid" /var/lib/stature
exposure=$(on_board systemd-analyze security stature 2>/dev/null | tail -1 | sed 's/.*exposure level for stature.service: //')
check "systemd-analyze security: $exposure" eval '[[ -n $exposure ]]'
caps="$(unit MemoryMax) $(unit CPUQuotaPerSecUSec)"
check "the profile's [board] caps are in force: MemoryMax=128M, CPUQuota=200% ($caps)" is "$caps" "134217728 2s"

# Restart: the stop writes the calibration state, the start resumes it.
on_board sudo systemctl restart stature
state=$(on_board sudo stat -c "'%U:%G %a, %s bytes'" /var/lib/stature/calibration.state 2>&1 || true)
check "calibration state in the StateDirectory after a stop ($state)" eval '[[ $state == stature:stature* ]]'
check "the restarted service resumes the state" wait_for 60 journal_has 'calibration state /var/lib/stature/calibration.state: resumed'
check "a second hello after the restart reaches the same listener (new source port)" wait_for 120 records count hello 2

# Restart=on-failure: SIGKILL is a failure.
pid=$(unit MainPID)
on_board sudo kill -KILL "$pid"
restarted() { [[ $(unit NRestarts) == 1 && $(unit ActiveState) == active && $(unit MainPID) != "$pid" && $(unit MainPID) != 0 ]]; }
check "SIGKILL: Restart=on-failure starts it again" wait_for 60 restarted
echo "       NRestarts $(unit NRestarts), $(unit ActiveState), pid $pid -> $(unit MainPID)"
check "reports resume on the workstation after the kill" wait_for 120 records count hello 3

# Unplug the camera (what a USB unplug looks like to the driver), plug it back.
on_board "echo vivid.0 | sudo tee /sys/bus/platform/drivers/vivid/unbind >/dev/null"
check "camera unplugged: status records say reconnecting" wait_for 120 records after-last-hello reconnecting
check "the service stays up without its camera" is "$(on_board systemctl is-active stature)" active
on_board "echo vivid.0 | sudo tee /sys/bus/platform/drivers/vivid/bind >/dev/null"
check "camera back: status records say streaming again" wait_for 120 records after-reconnecting streaming

# No camera at start (a USB camera that enumerates late, or is plugged in
# later): exit 3, and systemd retries every RestartSec=5 for as long as it
# takes, not only for the unit's start limit.
on_board "echo vivid.0 | sudo tee /sys/bus/platform/drivers/vivid/unbind >/dev/null"
restarts0=$(unit NRestarts)
hellos=$(records n hello)
on_board sudo systemctl restart stature || true
sleep 90
restarts=$(unit NRestarts)
echo "       after 90 s without a camera: $(unit ActiveState)/$(unit SubState), result $(unit Result), NRestarts $restarts0 -> $restarts"
check "without a camera at start it exits 3 and is retried (NRestarts $restarts0 -> $restarts)" eval '((restarts > restarts0 + 5))'
check "the service has not given up after 90 s" eval '[[ $(unit Result) != start-limit-hit && $(unit ActiveState) != failed ]]'
on_board "echo vivid.0 | sudo tee /sys/bus/platform/drivers/vivid/bind >/dev/null"
check "camera plugged in after 90 s: the service streams from it" wait_for 60 records count hello $((hellos + 1))

# Enabled: up again after a reboot, from its saved state.
hellos=$(records n hello)
on_board sudo systemctl reboot || true
sleep 10
wait_ssh 600
check "after a reboot the service is active (enabled at boot)" wait_for 120 eval '[[ $(on_board systemctl is-active stature) == active ]]'
check "reports arrive after the reboot" wait_for 120 records count hello $((hellos + 1))
check "after the reboot it resumes the calibration state" journal_has 'calibration state.*resumed'

# --- 5. The README's Pi Zero 2 row, as an upgrade of the same board ("run
#        the installer again"): the static musl build and rpi-zero2.toml,
#        whose UART sink (/dev/serial0, group dialout, DeviceAllow
#        char-ttyAMA) writes beside UDP.
zero2_build=$(sed -n 's/^| Raspberry Pi Zero 2 W .*| `\(cross\/build\.sh [^`]*\)`.*$/\1/p' "$readme")
[[ -n $zero2_build ]] || die "no Raspberry Pi Zero 2 build command in the README's table"
zero2_target=${zero2_build##* }
echo "--- README step 2 for a Pi Zero 2: $zero2_build"
(cd "$repo" && $zero2_build >"$run/zero2-build.log" 2>&1) || { tail -20 "$run/zero2-build.log"; die "$zero2_build failed"; }
sed -e "s/aarch64-unknown-linux-gnu/$zero2_target/g" -e "s/rpi4-aarch64\.toml/rpi-zero2.toml/g" "$run/steps34.sh" >"$run/zero2-steps34.sh"
echo "--- README steps 3 and 4 for a Pi Zero 2"
sed 's/^/    $ /' "$run/zero2-steps34.sh"
hellos=$(records n hello)
(cd "$repo" && export -f ssh scp && export run && bash -eo pipefail "$run/zero2-steps34.sh") \
    >"$run/zero2-steps34.log" 2>&1 || { cat "$run/zero2-steps34.log"; die "README steps 3-4 (Pi Zero 2) failed"; }
sed 's/^/    | /' "$run/zero2-steps34.log"
check "Zero 2 profile: the unedited Pi 4 config is replaced by the upgrade" grep -q "was as last installed" "$run/zero2-steps34.log"
check "Zero 2 profile: a new hello over UDP" wait_for 120 records count hello $((hellos + 1))
check "Zero 2 profile: 640x480 YUYV ($(records last hello))" records hello-mode 640 480 YUYV
musl_sum=$(sha256sum "$target_dir/$zero2_target/release/stature" | cut -c1-64)
check "Zero 2 profile: the installed binary is the static $zero2_target build" \
    is "$(on_board sha256sum /usr/local/bin/stature | cut -c1-64)" "$musl_sum"
uart_records() { python3 "$here/deploy_check.py" "$run/uart.log" "$@"; }
check "Zero 2 profile: records on the UART sink (/dev/serial0) under the hardened unit" wait_for 120 uart_records count status 1
echo "       UART: $(uart_records last hello)"
caps="$(unit MemoryMax) $(unit CPUQuotaPerSecUSec)"
check "Zero 2 profile: its caps replace the Pi 4's: MemoryMax=48M, CPUQuota=300% ($caps)" is "$caps" "50331648 3s"
echo "--- service log (sudo journalctl -u stature -b)"
on_board sudo journalctl -u stature -b --no-pager | tail -15 | sed 's/^/    | /'
echo "--- first records on the workstation"
head -3 "$run/udp.jsonl" | cut -c1-200 | sed 's/^/    | /'
records summary
if [[ -n "${DEPLOY_KEEP:-}" ]]; then
    say "VM left running: ssh -F $run/ssh_config pi@camera.local (qemu pid $qemu_pid)"
else
    on_board sudo systemctl poweroff || true
    wait "$qemu_pid" 2>/dev/null || true
    qemu_pid=""
fi
if [[ ${#failures[@]} -gt 0 ]]; then
    printf '  - %s\n' "${failures[@]}" >&2
    die "${#failures[@]} check(s) failed"
fi
say "all checks passed"
