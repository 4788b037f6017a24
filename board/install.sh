#!/bin/sh
# Installs stature on a board (run as root on the board):
#   sh install.sh --profile rpi4-aarch64.toml [--binary ./stature]
#                 [--report udp:192.168.1.20:9000]... [--replace-config] [--no-systemd]
# Copies the binary to /usr/local/bin, the profile to /etc/stature/stature.toml
# (--report replaces the profile's placeholder sink "udp:127.0.0.1:9000";
# other sinks, e.g. a UART, stay), the unit to /etc/systemd/system, the
# config's [board] caps into a unit drop-in; creates the `stature` system
# user in groups video and dialout; enables and starts the service.
# Run it again to upgrade: an /etc/stature/stature.toml you edited (an MQTT
# password, other sinks) is kept and the new profile goes beside it as
# stature.toml.dist; one left as installed is replaced by the new profile.
# --replace-config replaces it anyway, the old one saved as stature.toml.old.
# The config is root:stature, mode 0640: the service reads it, other users
# do not (it may hold a broker password).
# POSIX sh and busybox-compatible; DESTDIR=/some/root installs into a tree
# (an empty one is fine; with systemd, the unit is enabled there for boot).
set -eu

here=$(cd "$(dirname "$0")" && pwd)
profile=""
binary=""
reports=""
systemd=1
replace_config=0
while [ $# -gt 0 ]; do
    case "$1" in
        --profile | --binary | --report)
            [ $# -ge 2 ] || { echo "install.sh: $1 needs a value (see --help)" >&2; exit 2; } ;;
    esac
    case "$1" in
        --profile) profile=$2; shift 2 ;;
        --binary) binary=$2; shift 2 ;;
        --report)
            # A TOML basic string: a quote or backslash would end or escape it.
            # A TOML basic string holds no control characters (a newline
            # would end it mid-line and the service would refuse the file).
            case "${2-}" in
                "" | *\"* | *\\* | *[[:cntrl:]]*)
                    echo "install.sh: --report needs a sink URI without quotes, backslashes or control characters" >&2; exit 2 ;;
            esac
            reports="$reports${reports:+, }\"$2\""; shift 2 ;;
        --replace-config) replace_config=1; shift ;;
        --no-systemd) systemd=0; shift ;;
        -h|--help) sed -n '2,17p' "$0"; exit 0 ;;
        *) echo "install.sh: unknown option $1 (see --help)" >&2; exit 2 ;;
    esac
done
[ -n "$profile" ] || { echo "install.sh: --profile FILE is required (one of $here/*.toml)" >&2; exit 2; }
[ -f "$profile" ] || profile=$here/$profile
[ -f "$profile" ] || { echo "install.sh: no profile $profile" >&2; exit 2; }
if [ -z "$binary" ]; then
    for b in "$here/stature" "$here/../stature" "$(pwd)/stature"; do
        [ -x "$b" ] && binary=$b && break
    done
fi
[ -n "$binary" ] && [ -x "$binary" ] || { echo "install.sh: no stature binary (use --binary PATH)" >&2; exit 2; }
D=${DESTDIR:-}
if [ -n "$D" ]; then
    # A new, empty tree: the user and group files start empty.
    mkdir -p "$D/etc"
    [ -f "$D/etc/group" ] || : >"$D/etc/group"
    [ -f "$D/etc/passwd" ] || : >"$D/etc/passwd"
fi

# --- user and groups (shadow utils, busybox adduser, or plain files on
# images that have neither).
has() { command -v "$1" >/dev/null 2>&1; }
group_exists() { grep -q "^$1:" "$D/etc/group"; }
user_exists() { grep -q "^$1:" "$D/etc/passwd"; }
# The stature user's (passwd) or group's (group) numeric id in the tree.
stature_id() { grep '^stature:' "$D/etc/$1" | cut -d: -f3; }
add_group() {
    group_exists "$1" && return 0
    if [ -z "$D" ] && has groupadd; then groupadd --system "$1"
    elif [ -z "$D" ] && has addgroup; then addgroup -S "$1"
    else
        gid=999
        while cut -d: -f3 "$D/etc/group" | grep -qx "$gid"; do gid=$((gid - 1)); done
        echo "$1:x:$gid:" >>"$D/etc/group"
    fi
}
add_group stature
add_group video
add_group dialout
if ! user_exists stature; then
    if [ -z "$D" ] && has useradd; then
        useradd --system --gid stature --no-create-home --home-dir /var/lib/stature \
            --shell /usr/sbin/nologin --comment "stature camera service" stature
    elif [ -z "$D" ] && has adduser; then
        adduser -S -D -H -h /var/lib/stature -s /sbin/nologin -G stature stature
    else
        gid=$(stature_id group)
        uid=$gid
        while cut -d: -f3 "$D/etc/passwd" | grep -qx "$uid"; do uid=$((uid - 1)); done
        echo "stature:x:$uid:$gid:stature camera service:/var/lib/stature:/sbin/nologin" >>"$D/etc/passwd"
    fi
fi
# Supplementary groups: append the user to video and dialout.
for g in video dialout; do
    line=$(grep "^$g:" "$D/etc/group")
    members=${line##*:}
    case ",$members," in
        *,stature,*) ;;
        *) if [ -z "$D" ] && has usermod; then usermod -a -G "$g" stature
           else sed -i "s/^$g:\([^:]*\):\([^:]*\):\(.*\)\$/$g:\1:\2:\3${members:+,}stature/" "$D/etc/group"; fi ;;
    esac
done

# --- files.
mkdir -p "$D/usr/local/bin" "$D/etc/stature" "$D/etc/systemd/system/stature.service.d"
conf=$D/etc/stature/stature.toml
if [ -n "$reports" ]; then
    # Profiles name the workstation as the placeholder udp:127.0.0.1:9000.
    grep -q '"udp:127.0.0.1:9000"' "$profile" || {
        echo "install.sh: $profile has no \"udp:127.0.0.1:9000\" sink for --report to replace" >&2
        exit 2
    }
    # `&` (the matched text) and `|` (the delimiter) are special in the
    # replacement: mqtt:HOST?topic=a&qos=1 must arrive as written.
    escaped=$(printf '%s\n' "$reports" | sed 's/[&|]/\\&/g')
    sed "s|\"udp:127.0.0.1:9000\"|$escaped|" "$profile" >"$conf.new"
else
    cp "$profile" "$conf.new"
fi
# Root-owned, readable by the service's group only. Numeric ids: under
# DESTDIR the tree's group file counts, not this machine's.
protect() {
    chmod 0640 "$1" || [ -n "$D" ] || {
        echo "install.sh: cannot make $1 mode 0640 (run as root)" >&2
        exit 1
    }
    gid=$(stature_id group)
    chown "0:$gid" "$1" 2>/dev/null || [ -n "$D" ] || {
        echo "install.sh: cannot give $1 to group stature (run as root)" >&2
        exit 1
    }
}
protect "$conf.new"
# stature.toml.dist is the profile as this script last wrote it: a config
# equal to it was not edited, and an upgrade may replace it.
edited=0
if [ -f "$conf" ] && ! cmp -s "$conf" "$conf.new" && ! { [ -f "$conf.dist" ] && cmp -s "$conf" "$conf.dist"; }; then
    edited=1
fi
keep=0
[ "$edited" = 1 ] && [ "$replace_config" = 0 ] && keep=1
if [ "$keep" = 1 ]; then caps_from=$conf; else caps_from=$conf.new; fi
# Board caps from the [board] section of the config the service will read
# -> systemd resource control; read before anything is replaced.
# A TOML integer as a board profile writes it (`1_024` is 1024, a comment
# may follow); anything else is refused rather than read as its leading
# digits (`1_024` once became MemoryMax=1M).
board_value() {
    v=$(sed -n '/^[[:space:]]*\[board\]/,/^[[:space:]]*\[/ s/^[[:space:]]*'"$1"'[[:space:]]*=[[:space:]]*\([^#]*\).*/\1/p' "$caps_from" | head -1 | tr -d '[:space:]_')
    case "$v" in
        *[!0-9]*)
            echo "install.sh: [board] $1 = $v in $caps_from is not a whole number this script can read (write it as plain digits); nothing was installed" >&2
            rm -f "$conf.new"
            exit 2 ;;
    esac
    echo "$v"
}
mem=$(board_value memory_max_mib)
cpu=$(board_value cpu_quota_percent)
# The config the service will read, checked by the new binary before
# anything is replaced (when it runs here, i.e. not into a DESTDIR tree).
# Its keys only: the state directory is made by systemd when the service
# first starts, and the service's user is not this one.
if [ -z "$D" ]; then
    if [ "$keep" = 1 ]; then checked=$conf; else checked=$conf.new; fi
    "$binary" config --check "$checked" --keys-only || {
        if [ "$keep" = 1 ]; then
            # What to merge the edits into is needed now more than ever.
            mv -f "$conf.new" "$conf.dist"
            echo "install.sh: your $checked is refused by the new binary (the new profile is in $conf.dist); the binary and the config were left as they were" >&2
        else
            rm -f "$conf.new"
            echo "install.sh: $checked is refused by the new binary; the binary and the config were left as they were" >&2
        fi
        exit 2
    }
fi
if [ "$keep" = 1 ]; then
    mv -f "$conf.new" "$conf.dist"
    # A symlink points at a file managed elsewhere: its owner sets its mode.
    [ -L "$conf" ] || protect "$conf"
    echo "install.sh: kept your edited $conf; the new profile (and any --report) is in $conf.dist (compare them; --replace-config installs it)"
else
    if [ "$edited" = 1 ]; then
        cp -p "$conf" "$conf.old"
        echo "install.sh: replaced your edited $conf (--replace-config); it is saved as $conf.old"
    elif [ -f "$conf" ] && ! cmp -s "$conf" "$conf.new"; then
        echo "install.sh: $conf was as last installed (not edited): replaced by the new profile"
    fi
    cp -p "$conf.new" "$conf.dist"
    mv -f "$conf.new" "$conf"
fi
# Copy then rename: replacing a running binary in place would fail (ETXTBSY).
cp "$binary" "$D/usr/local/bin/.stature.new"
chmod 0755 "$D/usr/local/bin/.stature.new"
mv -f "$D/usr/local/bin/.stature.new" "$D/usr/local/bin/stature"
cp "$here/stature.service" "$D/etc/systemd/system/stature.service"
chmod 0644 "$D/etc/systemd/system/stature.service"
{
    echo "# From the [board] section of /etc/stature/stature.toml (board/install.sh;"
    echo "# run it again after changing those caps there)."
    echo "[Service]"
    [ -n "$mem" ] && [ "$mem" != 0 ] && echo "MemoryMax=${mem}M"
    [ -n "$cpu" ] && [ "$cpu" != 0 ] && echo "CPUQuota=${cpu}%"
    true
} >"$D/etc/systemd/system/stature.service.d/board.conf"

# --- service.
if [ "$systemd" = 1 ] && [ -z "$D" ] && has systemctl && [ -d /run/systemd/system ]; then
    systemctl daemon-reload
    systemctl enable stature.service
    systemctl restart stature.service
    echo "install.sh: stature enabled and started; logs: sudo journalctl -u stature -f"
elif [ "$systemd" = 1 ] && [ -n "$D" ]; then
    # An image being built: enabled as `systemctl enable` would (the
    # unit's WantedBy=), started when the image boots.
    mkdir -p "$D/etc/systemd/system/multi-user.target.wants"
    ln -sf /etc/systemd/system/stature.service "$D/etc/systemd/system/multi-user.target.wants/stature.service"
    echo "install.sh: stature enabled in $D; it starts when the image boots"
else
    # What StateDirectory= would create, the service user's. Numeric ids:
    # under DESTDIR the tree's files count, not this machine's (and a
    # build without root cannot chown: the image's builder does).
    mkdir -p "$D/var/lib/stature"
    chmod 0750 "$D/var/lib/stature"
    uid=$(stature_id passwd)
    gid=$(stature_id group)
    chown "$uid:$gid" "$D/var/lib/stature" 2>/dev/null || [ -n "$D" ] || {
        echo "install.sh: cannot give /var/lib/stature to user stature (run as root)" >&2
        exit 1
    }
    # su -s: busybox's setpriv has no --reuid; su (busybox or util-linux)
    # sets the user's groups (video, dialout) and overrides its nologin shell.
    echo "install.sh: installed without systemd; run as: su -s /bin/sh -c 'exec /usr/local/bin/stature run --config /etc/stature/stature.toml' stature"
fi
echo "install.sh: /usr/local/bin/stature, /etc/stature/stature.toml ($(sed -n 's/^name *= *//p' "$D/etc/stature/stature.toml" | head -1)), /etc/systemd/system/stature.service"
