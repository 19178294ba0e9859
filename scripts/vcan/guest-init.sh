#!/bin/bash
# PID 1 inside the vcan-run guest kernel (UML or QEMU); started by scripts/vcan-run.sh,
# never by hand. The host's root file system is this guest's root, so every host path is
# the same path here.
#
# From the kernel command line (unknown name=value parameters become init's environment):
#   VCAN_RUN_DIR   host directory of this run: job.sh (environment, cwd, command), and
#                  where started / rc are written
#   VCAN_RUN_OUT   guest tty that is the host's stdout; VCAN_RUN_ERR the same for stderr
#   VCAN_RUN_RAW_OUT, VCAN_RUN_RAW_ERR  "1": pass bytes unchanged (the host side is not a
#                  terminal); "0": keep the tty's newline -> CR LF (a host terminal in raw mode)
#   VCAN_RUN_IFACES  vcan interfaces to create (comma-separated, default vcan0)
export PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin
d="$VCAN_RUN_DIR"
out="${VCAN_RUN_OUT:-/dev/console}"
err="${VCAN_RUN_ERR:-/dev/console}"

say() { echo "vcan-run guest: $*" > "$err" 2>/dev/null || echo "vcan-run guest: $*" >&2; }
power_off() {
  sync
  # reboot(LINUX_REBOOT_CMD_POWER_OFF); perl-base is essential on Debian, busybox is not.
  perl -e 'syscall(169, 0xfee1dead, 672274793, 0x4321fedc)' 2>/dev/null
  echo o > /proc/sysrq-trigger 2>/dev/null
  exit 1
}

mount -t proc proc /proc
mount -t sysfs sysfs /sys
mountpoint -q /dev || mount -t devtmpfs devtmpfs /dev
mkdir -p /dev/pts /dev/shm
mount -t devpts -o gid=5,mode=620,ptmxmode=666 devpts /dev/pts
mount -t tmpfs -o mode=1777 tmpfs /dev/shm
# The host's /run stays the host's: give the guest its own.
mount -t tmpfs -o mode=755 tmpfs /run
hostname vcan-run 2>/dev/null


# CAN modules: Debian's UML keeps them under /usr/lib/uml/modules/VERSION (no modules.dep
# there), a normal kernel under /lib/modules/VERSION.
kver="$(uname -r)"
if [ -d "/usr/lib/uml/modules/$kver" ] && [ ! -d "/lib/modules/$kver" ]; then
  m="/usr/lib/uml/modules/$kver/kernel"
  for k in net/can/can.ko net/can/can-raw.ko net/can/can-bcm.ko net/can/can-gw.ko \
           net/can/can-isotp.ko drivers/net/can/dev/can-dev.ko drivers/net/can/vcan.ko \
           drivers/net/can/vxcan.ko; do
    [ -f "$m/$k" ] && insmod "$m/$k" 2>/dev/null
  done
else
  modprobe -qa can can-raw can-bcm can-gw can-isotp can-dev vcan vxcan 2>/dev/null
fi
ip link set lo up 2>/dev/null
ok=1
IFS=, read -r -a ifaces <<< "${VCAN_RUN_IFACES:-vcan0}"
for i in "${ifaces[@]}"; do
  [ -n "$i" ] || continue
  if ! { ip link add dev "$i" type vcan && ip link set up "$i"; } > "$err" 2>&1; then
    say "could not create $i (kernel $kver has no vcan?)"
    ok=0
  fi
done
if [ "$ok" != 1 ]; then
  echo 125 > "$d/rc.tmp" && mv "$d/rc.tmp" "$d/rc"
  power_off
fi

# Output: the command writes to pipes (as on the host), not to the guest's ttys, so
# isatty() answers as it would in CI; two cats carry the bytes to the host's fds.
mkfifo /run/vcan-run-out /run/vcan-run-err
# The cats ignore SIGTERM, so that the clean-up below stops the command's leftovers first.
# The tty mode is set while the cat holds the tty open (hvc resets it on last close).
(trap '' TERM; [ "${VCAN_RUN_RAW_OUT:-1}" = 1 ] && stty raw -echo <&1 2>/dev/null
 exec cat /run/vcan-run-out) > "$out" & c1=$!
(trap '' TERM; [ "${VCAN_RUN_RAW_ERR:-1}" = 1 ] && stty raw -echo <&1 2>/dev/null
 exec cat /run/vcan-run-err) > "$err" & c2=$!

: > "$d/started"
(
  # shellcheck source=/dev/null
  . "$d/job.sh" || exit 125
  exec "${VCAN_RUN_CMD[@]}"
) < /dev/null > /run/vcan-run-out 2> /run/vcan-run-err
rc=$?

# Whatever the command left running is stopped (as when a container's main process
# exits); then the cats see end-of-file and finish writing. 3 s at most.
kill -TERM -1 2>/dev/null
for _ in $(seq 30); do
  kill -0 "$c1" 2>/dev/null || kill -0 "$c2" 2>/dev/null || break
  sleep 0.1
done
kill -KILL -1 2>/dev/null
echo "$rc" > "$d/rc.tmp" && mv "$d/rc.tmp" "$d/rc"
power_off
