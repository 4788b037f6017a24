#!/usr/bin/env bash
# Real V4L2 capture against the kernel's `vivid` driver, on an emulated
# aarch64 board (qemu-system-aarch64 -M virt -cpu cortex-a57, TCG).
#
# Builds a tiny initramfs from Debian's arm64 packages (kernel modules from
# linux-image-arm64, busybox-static), the cross sysroots' glibc, and the three
# release binaries (cross/build.sh), boots it, and inside the guest:
#   1. loads vivid and runs the static musl build's
#      `stature run --source v4l2:/dev/video0?...`; mid-run it unbinds the
#      vivid platform device through sysfs (what a USB unplug looks like) and
#      binds it again: the source must reconnect;
#   2. captures with the armv7 build (32-bit compat ioctls on a 64-bit kernel),
#      and runs the serial-sink test (aarch64 and armv7 builds) over a
#      pseudo-terminal (qemu-user lacks the TCGETS2 ioctl it needs);
#   3. deploys the aarch64 glibc build like a new user would (board/install.sh
#      with the rpi4 profile, the systemd unit's ExecStart run as the
#      dedicated user through su), its UDP reports read on the host with
#      `nc -ul` as the README says (qemu user networking: the guest's
#      10.0.2.2 is the host's loopback), and measures its peak RSS.
# Records leave the guest on virtio-serial ports (not the console, where
# kernel messages would split them) and are checked here on the host.
#
#   cross/vm-test.sh               # builds the musl binary if needed, runs, checks
#   STATURE_BIN=path cross/vm-test.sh   # (also STATURE_GNU_BIN, STATURE_ARMV7_BIN)
#   VM_FRAMES=300 cross/vm-test.sh
#
# Needs cross/install.sh. If the kernel package cannot be fetched the test
# fails (exit 1) when CI=true and is skipped (exit 0, with a message) otherwise.
set -euo pipefail

here=$(cd "$(dirname "$0")" && pwd)
repo=$(dirname "$here")
target_dir=${CARGO_TARGET_DIR:-$repo/target}
cache=${CROSS_CACHE:-$target_dir/cross-cache}
work=$cache/vm
frames=${VM_FRAMES:-250}
mkdir -p "$cache" "$work"

die() { echo "vm-test: FAIL: $*" >&2; exit 1; }
skip_or_die() {
    if [[ "${CI:-}" == "true" ]]; then
        die "$*"
    fi
    echo "vm-test: SKIP: $* (set CI=true to make this a failure)" >&2
    exit 0
}

# --- 1. Debian arm64 packages through a private apt state (the host's apt
#        configuration and architecture list stay untouched).
aptdir=$cache/apt
mkdir -p "$aptdir/lists/partial" "$aptdir/cache/archives/partial" "$cache/debs"
apt_opts=(-o "Dir::State::Lists=$aptdir/lists" -o "Dir::Cache=$aptdir/cache"
    -o APT::Architecture=arm64 -o APT::Architectures::=arm64
    -o Dir::State::status=/dev/null -o Debug::NoLocking=1
    -o APT::Sandbox::User=root)
fetch_debs() {
    ls "$cache"/debs/linux-image-*-arm64_*.deb "$cache"/debs/busybox-static_*.deb >/dev/null 2>&1 && return 0
    apt-get -qq "${apt_opts[@]}" update || return 1
    local kpkg
    kpkg=$(apt-cache "${apt_opts[@]}" depends linux-image-arm64 2>/dev/null |
        awk '/Depends: linux-image-[0-9]/ {print $2; exit}')
    [[ -n "$kpkg" ]] || return 1
    (cd "$cache/debs" && apt-get -qq "${apt_opts[@]}" download "$kpkg" busybox-static) || return 1
}
fetch_debs || skip_or_die "cannot obtain Debian's arm64 kernel package (linux-image-arm64) or busybox-static with apt-get download"

for tool in qemu-system-aarch64 depmod cpio; do
    command -v $tool >/dev/null || skip_or_die "$tool missing: run cross/install.sh"
done

kdeb=$(ls "$cache"/debs/linux-image-*-arm64_*.deb | head -1)
kroot=$cache/kernel
if [[ ! -f $kroot/.done ]] || [[ $(cat "$kroot/.done") != "$(basename "$kdeb")" ]]; then
    rm -rf "$kroot"
    mkdir -p "$kroot"
    dpkg-deb -x "$kdeb" "$kroot"
    basename "$kdeb" >"$kroot/.done"
fi
kver=$(ls "$kroot/lib/modules" | head -1)
# Debian's package ships no modules.dep: make one with the host's depmod.
[[ -f $kroot/lib/modules/$kver/modules.dep ]] || depmod -b "$kroot" "$kver"
vmlinuz=$kroot/boot/vmlinuz-$kver

bbroot=$cache/busybox
if [[ ! -x $bbroot/bin/busybox ]]; then
    rm -rf "$bbroot"
    dpkg-deb -x "$(ls "$cache"/debs/busybox-static_*.deb | head -1)" "$bbroot"
fi

# --- 2. The static musl binary.
musl_bin=${STATURE_BIN:-$target_dir/aarch64-unknown-linux-musl/release/stature}
if [[ -z "${STATURE_BIN:-}" ]]; then
    (cd "$repo" && cargo build --release --locked --features v4l2 --target aarch64-unknown-linux-musl --bin stature)
fi
[[ -x $musl_bin ]] || die "no binary at $musl_bin"
file "$musl_bin" | grep -q 'statically linked' || die "$musl_bin is not statically linked"
# The glibc builds (cross/build.sh) run too: aarch64-gnu is what the README
# deploys to a Pi 4; armv7 exercises the kernel's 32-bit (compat) V4L2 ioctls.
gnu_bin=${STATURE_GNU_BIN:-$target_dir/aarch64-unknown-linux-gnu/release/stature}
armv7_bin=${STATURE_ARMV7_BIN:-$target_dir/armv7-unknown-linux-gnueabihf/release/stature}
for b in "$gnu_bin" "$armv7_bin"; do
    [[ -x $b ]] || die "no binary at $b (run cross/build.sh)"
done
# The serial-sink test binaries (cross/test.sh built them): qemu-user cannot
# run them (no TCGETS2), a real kernel can: aarch64 natively, armv7 through
# the kernel's 32-bit compat layer.
sinks_bin() { ls -t "$target_dir/$1"/release/deps/sinks-* 2>/dev/null | grep -v '\.d$' | head -1 || true; }
sinks_test=$(sinks_bin aarch64-unknown-linux-gnu)
sinks_test_armv7=$(sinks_bin armv7-unknown-linux-gnueabihf)
if [[ -z $sinks_test || -z $sinks_test_armv7 ]]; then
    [[ "${CI:-}" == "true" ]] && die "no aarch64 and armv7 sinks test binaries: run cross/test.sh first"
    echo "vm-test: no aarch64 and armv7 sinks test binaries (cross/test.sh builds them): serial test skipped"
    sinks_test="" sinks_test_armv7=""
fi

# --- 3. The unit as systemd reads it (the guest has no systemd): every
# directive known and valid, ExecStart pointed at a binary that exists here.
if command -v systemd-analyze >/dev/null; then
    unitdir=$work/unit
    mkdir -p "$unitdir"
    sed "s|/usr/local/bin/stature|$musl_bin|" "$repo/board/stature.service" >"$unitdir/stature.service"
    if ! msg=$(systemd-analyze verify "$unitdir/stature.service" 2>&1) || [[ -n $msg ]]; then
        die "systemd-analyze verify board/stature.service: $msg"
    fi
    echo "vm-test: board/stature.service verifies with systemd-analyze"
fi

# --- 4. The initramfs.
# The host side of the README's `nc -ul 9000` listens on a free port.
udp_port=$(python3 -c 'import socket; s=socket.socket(socket.AF_INET, socket.SOCK_DGRAM); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
root=$work/root
rm -rf "$root"
mkdir -p "$root"/{bin,sbin,usr/bin,usr/sbin,etc,proc,sys,dev,tmp,run,var/lib,deploy/board,deploy/bin}
cp "$bbroot/bin/busybox" "$root/bin/busybox"
ln -s busybox "$root/bin/sh"
# Modules: vivid, the virtio-serial console ports, and everything they need
# (from modules.dep), in the same tree so that busybox modprobe finds them.
mods=(vivid virtio_mmio virtio_console virtio_net)
mdir=lib/modules/$kver
mkdir -p "$root/$mdir"
cp "$kroot/$mdir"/modules.{dep,alias,symbols,builtin,order} "$root/$mdir/" 2>/dev/null || true
for m in "${mods[@]}"; do
    line=$(grep -E "/$m\.ko(\.[a-z]+)?:" "$kroot/$mdir/modules.dep") || die "module $m not in $kver"
    for f in ${line/:/}; do
        mkdir -p "$root/$mdir/$(dirname "$f")"
        cp "$kroot/$mdir/$f" "$root/$mdir/$f"
    done
done
# glibc like a Debian board has it (multiarch layout, so that both fit).
for pair in aarch64-linux-gnu:ld-linux-aarch64.so.1 arm-linux-gnueabihf:ld-linux-armhf.so.3; do
    triplet=${pair%%:*} ld=${pair#*:}
    mkdir -p "$root/lib/$triplet"
    cp -L "/usr/$triplet/lib/$ld" "$root/lib/$ld"
    for lib in libc.so.6 libgcc_s.so.1 libm.so.6; do
        cp -L "/usr/$triplet/lib/$lib" "$root/lib/$triplet/"
    done
done
# The binaries go in without their debug info: the guest's root file
# system lives in its 512 MiB of RAM, and five binaries with debug info
# (30-34 MB each) plus the installed copy left it full.
payload() { # SRC DST STRIP-TOOL
    if command -v "$3" >/dev/null; then
        "$3" --strip-debug -o "$2" "$1"
    else
        cp "$1" "$2"
    fi
}
payload "$musl_bin" "$root/bin/stature-musl" aarch64-linux-gnu-strip
if [[ -n $sinks_test ]]; then
    payload "$sinks_test" "$root/bin/sinks-test" aarch64-linux-gnu-strip
    payload "$sinks_test_armv7" "$root/bin/sinks-test-armv7" arm-linux-gnueabihf-strip
fi
payload "$armv7_bin" "$root/bin/stature-armv7" arm-linux-gnueabihf-strip
# Deployment payload, as a user would scp it to the board (README: the
# aarch64-unknown-linux-gnu build for a Pi 4).
payload "$gnu_bin" "$root/deploy/bin/stature" aarch64-linux-gnu-strip
cp "$repo"/board/*.toml "$repo/board/stature.service" "$repo/board/install.sh" "$root/deploy/board/"
# A minimal passwd/group like a board image has (busybox adduser fills them in).
printf 'root:x:0:0:root:/root:/bin/sh\n' >"$root/etc/passwd"
printf 'root:x:0:\nvideo:x:44:\ndialout:x:20:\n' >"$root/etc/group"
# Hotplug like udev on a board: video nodes group video, mode 0660.
printf 'video[0-9]+ root:video 0660\n' >"$root/etc/mdev.conf"
cat >"$root/etc/vm.toml" <<EOF
# vm-test: status every second of stream time so the checks see many.
[report]
status_interval_s = 1.0
EOF

cat >"$root/init" <<EOF
#!/bin/sh
/bin/busybox --install -s
export PATH=/bin:/sbin:/usr/bin:/usr/sbin
mount -t proc proc /proc
mount -t sysfs sys /sys
mount -t devtmpfs dev /dev
mount -t tmpfs tmp /tmp
echo /sbin/mdev >/proc/sys/kernel/hotplug
say() { echo "VMTEST: \$*"; echo "VMTEST: \$*" >>/dev/vport0p3; }
modprobe virtio_mmio; modprobe virtio_console
for i in 1 2 3 4 5 6 7 8 9 10; do [ -e /dev/vport0p3 ] && break; sleep 0.2; done
say "kernel \$(uname -r) \$(uname -m)"
modprobe vivid n_devs=1 node_types=0x1 || say "modprobe vivid failed"
for i in 1 2 3 4 5 6 7 8 9 10; do [ -e /dev/video0 ] && break; sleep 0.2; done
mdev -s
say "devices: \$(ls /dev/video* 2>&1)"

# Part 1: capture with an unplug/replug in the middle (static musl build).
/bin/stature-musl run --config /etc/vm.toml \\
    --source 'v4l2:/dev/video0?width=640&height=480&fps=25&format=YUYV' \\
    --frames $frames --report file:/dev/vport0p1 --report file:/tmp/r.jsonl \\
    2>/dev/vport0p2 &
pid=\$!
# Unplug once a third of the frames have been processed.
n=0
while kill -0 \$pid 2>/dev/null; do
    last=\$(grep '"type":"status"' /tmp/r.jsonl 2>/dev/null | tail -1 | sed 's/.*"frames":\([0-9]*\).*/\1/')
    [ -n "\$last" ] && [ "\$last" -ge $((frames / 3)) ] && break
    sleep 0.2; n=\$((n + 1)); [ \$n -gt 600 ] && break
done
say "unplug at frame \$last"
echo vivid.0 >/sys/bus/platform/drivers/vivid/unbind && say "unbound"
sleep 3
say "devices while unplugged: \$(ls /dev/video* 2>&1)"
echo vivid.0 >/sys/bus/platform/drivers/vivid/bind && say "bound again"
mdev -s
say "devices after replug: \$(ls -l /dev/video* 2>&1)"
wait \$pid
say "stature exit \$?"

# Part 1b: the 32-bit armv7 build on the same device (compat ioctls).
/bin/stature-armv7 run --config /etc/vm.toml \\
    --source 'v4l2:/dev/video0?width=640&height=480&fps=25&format=YUYV' \\
    --frames 50 --report file:/dev/vport0p4 2>>/dev/vport0p2
say "armv7 exit \$?"

# Part 1c: the serial sink over a pseudo-terminal (tests/sinks.rs).
if [ -x /bin/sinks-test ]; then
    mkdir -p /dev/pts && mount -t devpts devpts /dev/pts
    /bin/sinks-test serial_sink --test-threads=1 >>/dev/vport0p2 2>&1
    say "serial test exit \$?"
    /bin/sinks-test-armv7 serial_sink --test-threads=1 >>/dev/vport0p2 2>&1
    say "serial test armv7 exit \$?"
else
    say "serial test skipped"
fi

# Part 2: deploy as the README says, on this "board".
modprobe virtio_net
ifconfig lo 127.0.0.1 up
ifconfig eth0 10.0.2.15 netmask 255.255.255.0 up
cd /deploy
sh board/install.sh --profile board/rpi4-aarch64.toml --binary bin/stature \\
    --report udp:10.0.2.2:$udp_port --no-systemd >/tmp/install.log 2>&1
say "install exit \$? \$(tr '\n' '|' </tmp/install.log)"
say "user: \$(id stature 2>&1)"
# The unit's ExecStart, as systemd would run it: dedicated user, its groups.
exec_start=\$(sed -n 's/^ExecStart=//p' /etc/systemd/system/stature.service)
say "ExecStart: \$exec_start"
# (busybox su: switches uid, gid and supplementary groups like User=/SupplementaryGroups=)
# Peak RSS of the 1280x720 run as a real aarch64 kernel counts it (VmHWM,
# read until the process ends; busybox's 'time -v' over-reports it 4x).
su -s /bin/sh -c "\$exec_start --frames 60" stature 2>>/dev/vport0p2 &
supid=\$!
hwm=""
while kill -0 \$supid 2>/dev/null; do
    p=\$(pidof stature)
    h=\$([ -n "\$p" ] && sed -n 's/^VmHWM: *//p' /proc/\$p/status 2>/dev/null)
    [ -n "\$h" ] && hwm=\$h
    sleep 0.2
done
wait \$supid
say "service run exit \$?"
say "peak RSS VmHWM \$hwm"
say "state dir: \$(ls -ld /var/lib/stature 2>&1)"
say "done"
sync
poweroff -f
EOF
chmod +x "$root/init"
(cd "$root" && find . | cpio -o -H newc --quiet | gzip -1) >"$work/initramfs.gz"

# --- 5. Boot.
out=$work/out
rm -rf "$out"
mkdir -p "$out"
: >"$out/reports.jsonl"
: >"$out/stderr.log"
: >"$out/marks.log"
: >"$out/udp.jsonl"
: >"$out/armv7.jsonl"
nc -dul 127.0.0.1 "$udp_port" >"$out/udp.jsonl" &
nc_pid=$!
trap 'kill $nc_pid 2>/dev/null || true' EXIT
echo "vm-test: booting $kver with $(du -h "$work/initramfs.gz" | cut -f1) initramfs, $frames frames"
start=$(date +%s)
set +e
timeout 600 qemu-system-aarch64 -M virt -cpu cortex-a57 -smp 2 -m 512 -accel tcg \
    -nographic -no-reboot \
    -netdev user,id=n0 -device virtio-net-device,netdev=n0 \
    -kernel "$vmlinuz" -initrd "$work/initramfs.gz" \
    -append "console=ttyAMA0 loglevel=4 panic=-1 rdinit=/init" \
    -device virtio-serial-device \
    -chardev file,id=reports,path="$out/reports.jsonl" \
    -device virtserialport,chardev=reports,name=reports,nr=1 \
    -chardev file,id=stderr,path="$out/stderr.log" \
    -device virtserialport,chardev=stderr,name=stderr,nr=2 \
    -chardev file,id=marks,path="$out/marks.log" \
    -device virtserialport,chardev=marks,name=marks,nr=3 \
    -chardev file,id=armv7,path="$out/armv7.jsonl" \
    -device virtserialport,chardev=armv7,name=armv7,nr=4 \
    >"$out/console.log" 2>&1 </dev/null
rc=$?
set -e
sleep 0.5
kill $nc_pid 2>/dev/null || true
echo "vm-test: guest ran $(($(date +%s) - start)) s (qemu exit $rc)"
[[ $rc -eq 0 ]] || { tail -30 "$out/console.log"; die "qemu exited $rc"; }

# --- 6. Checks, on the host.
if ! grep -q "VMTEST: done" "$out/marks.log"; then
    tail -40 "$out/console.log"
    die "the guest did not finish its script (console above)"
fi
echo "--- guest marks"; cat "$out/marks.log"
echo "--- stature stderr"; cat "$out/stderr.log"
python3 "$here/vm_check.py" "$out" "$frames"
