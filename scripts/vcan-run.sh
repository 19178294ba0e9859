#!/usr/bin/env bash
# Runs one command where a SocketCAN vcan interface (vcan0) is up: on the host kernel when
# it has vcan, else inside a Linux kernel started for the purpose (User-Mode Linux, or
# QEMU) whose root file system is the host's, so every path, the working directory and the
# environment are the same inside. The command's stdout/stderr come out on ours and its
# exit status is ours. See docs/results/vcan-runner.md.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
vdir="$here/vcan"
prog="vcan-run"

usage() {
  cat <<'TXT'
usage: scripts/vcan-run.sh [OPTIONS] -- COMMAND [ARGS...]
       scripts/vcan-run.sh [OPTIONS] --probe

Runs COMMAND with the vcan interface(s) up, in the current directory and environment.
Exit status: COMMAND's; 124 on --timeout; 125 when no backend could run it; 2 for bad use.

  --backend B   auto (default) | host | uml | qemu
                auto: the host kernel if it has vcan (or vcan0 exists), else User-Mode
                Linux, else QEMU (KVM when /dev/kvm works, else TCG)
  --iface NAME  vcan interface to create (repeatable; default vcan0)
  --mem SIZE    guest memory, e.g. 512M (default 1G; uml/qemu)
  --timeout S   stop the guest after S seconds (exit 124)
  --probe       check that the backend works (runs `true`), print it, exit 0 or 125
  --keep        keep the run directory (job file, guest console log) and print its path
  -v, --verbose print the guest kernel's console log on stderr afterwards
  -h, --help    this text

Inside a guest: stdin is /dev/null; $VCAN_RUN_BACKEND names the backend; processes the
command leaves running are stopped when it exits. Run several programs with one shell
command, e.g. -- bash -c 'a & b; wait'.
Environment: VCAN_RUN_BACKEND (default for --backend), VCAN_RUN_MEM, VCAN_RUN_CACHE
(where the UML shim and the QEMU initramfs are cached; default ~/.cache/bms-vcan-run),
VCAN_RUN_KERNEL_ARGS (appended to the guest kernel command line, e.g. loglevel=7 to see
the boot with -v), VCAN_RUN_QEMU_ACCEL (auto|kvm|tcg), VCAN_RUN_KVM_DEADLINE (s, 20).
TXT
}

say() { echo "$prog: $*" >&2; }
die() { echo "$prog: $*" >&2; exit 125; }
bad() { echo "$prog: $*" >&2; echo "try: scripts/vcan-run.sh --help" >&2; exit 2; }

backend="${VCAN_RUN_BACKEND:-auto}"
mem="${VCAN_RUN_MEM:-1G}"
timeout_s=0
ifaces=()
probe=0
keep=0
verbose=0
while [ $# -gt 0 ]; do
  case "$1" in
    --backend) [ $# -ge 2 ] || bad "--backend needs a value"; backend="$2"; shift 2 ;;
    --backend=*) backend="${1#*=}"; shift ;;
    --iface) [ $# -ge 2 ] || bad "--iface needs a value"; ifaces+=("$2"); shift 2 ;;
    --iface=*) ifaces+=("${1#*=}"); shift ;;
    --mem) [ $# -ge 2 ] || bad "--mem needs a value"; mem="$2"; shift 2 ;;
    --mem=*) mem="${1#*=}"; shift ;;
    --timeout) [ $# -ge 2 ] || bad "--timeout needs a value"; timeout_s="$2"; shift 2 ;;
    --timeout=*) timeout_s="${1#*=}"; shift ;;
    --probe) probe=1; shift ;;
    --keep) keep=1; shift ;;
    -v|--verbose) verbose=1; shift ;;
    -h|--help) usage; exit 0 ;;
    --) shift; break ;;
    -*) bad "unknown option '$1'" ;;
    *) break ;;
  esac
done
case "$backend" in auto|host|uml|qemu) ;; *) bad "--backend must be auto, host, uml or qemu, not '$backend'" ;; esac
[[ "$timeout_s" =~ ^[0-9]+$ ]] || bad "--timeout must be whole seconds, not '$timeout_s'"
[[ "$mem" =~ ^[0-9]+[MG]$ ]] || bad "--mem must look like 512M or 2G, not '$mem'"
[ ${#ifaces[@]} -gt 0 ] || ifaces=(vcan0)
for i in "${ifaces[@]}"; do
  [[ "$i" =~ ^[A-Za-z0-9_.-]{1,15}$ ]] || bad "bad interface name '$i'"
done
if [ "$probe" = 1 ]; then
  [ $# -eq 0 ] || bad "--probe takes no command"
  set -- true
fi
[ $# -gt 0 ] || bad "no command given (put it after --)"

cache="${VCAN_RUN_CACHE:-${XDG_CACHE_HOME:-${HOME:-/tmp}/.cache}/bms-vcan-run}"
install_hint="install it with scripts/install-deps.sh"
is_root() { [ "$(id -u)" -eq 0 ]; }

# ---------------------------------------------------------------- host
host_ready() {
  # The host kernel has vcan when the interfaces exist or can be created.
  local i
  for i in "${ifaces[@]}"; do
    if ! ip link show dev "$i" >/dev/null 2>&1; then
      command -v ip >/dev/null 2>&1 || return 1
      is_root || return 1
      modprobe -q vcan 2>/dev/null || true
      ip link add dev "$i" type vcan 2>/dev/null || return 1
    fi
    ip link show dev "$i" 2>/dev/null | grep -q 'state UP\|,UP' \
      || { is_root && ip link set up "$i" 2>/dev/null; } || return 1
  done
}

run_host() {
  say "backend host (kernel $(uname -r), ${ifaces[*]} up)"
  export VCAN_RUN_BACKEND=host
  exec "$@"
}

# ---------------------------------------------------------------- shared guest plumbing
rundir=""
guest_pid=""
watchdog_pid=""
saved_tty=""
tty_fd=2
cleanup() {
  if [ -n "$watchdog_pid" ]; then kill "$watchdog_pid" 2>/dev/null || true; fi
  if [ -n "$guest_pid" ]; then
    kill -KILL -- "-$guest_pid" 2>/dev/null || true
    # Gone before we exit: whoever waits for us may remove what the guest was writing.
    wait "$guest_pid" 2>/dev/null || true
    local n=0
    while kill -0 -- "-$guest_pid" 2>/dev/null && [ "$n" -lt 50 ]; do sleep 0.1; n=$((n + 1)); done
  fi
  if [ -n "$saved_tty" ]; then stty "$saved_tty" <&"$tty_fd" 2>/dev/null || true; fi
  if [ -n "$rundir" ] && [ "$keep" != 1 ]; then rm -rf "$rundir"; fi
}
trap cleanup EXIT
trap 'say "interrupted"; exit 130' INT
trap 'say "terminated"; exit 143' TERM

new_rundir() {
  local base="${TMPDIR:-/tmp}"
  [[ "$base" =~ ^/[A-Za-z0-9_./-]*$ ]] || base=/tmp   # it goes on a kernel command line
  rundir="$(mktemp -d "$base/vcan-run.XXXXXX")"
  cp "$vdir/guest-init.sh" "$rundir/init"
  chmod 755 "$rundir/init"
  # The command, its directory and environment, as one bash file the guest sources.
  {
    local n
    while IFS= read -r n; do
      case "$n" in
        SHLVL|PWD|OLDPWD|_|SHELLOPTS|BASHOPTS|BASH_*|VCAN_RUN_BACKEND) continue ;;
      esac
      printf 'export %s=%q\n' "$n" "${!n}"
    done < <(compgen -e)
    printf 'export VCAN_RUN_BACKEND=%q\n' "$1"
    printf 'cd -- %q || exit 125\n' "$PWD"
    shift
    printf 'VCAN_RUN_CMD=('
    printf '%q ' "$@"
    printf ')\n'
  } > "$rundir/job.sh"
}

iface_list() { local IFS=,; echo "${ifaces[*]}"; }
# 1: fd $1 is not a terminal, the guest tty passes bytes unchanged; 0: a terminal (which UML
# puts into raw mode), the guest tty adds the CR before LF. Not for use inside $(...).
raw_flag() { if [ -t "$1" ]; then raw=0; else raw=1; fi; }

# With --timeout: a watchdog that stops the guest's process group (guest_pid) in time.
start_watchdog() {
  if [ "$timeout_s" -gt 0 ]; then
    # Its own fds go nowhere, and it sleeps in 1 s steps, so nothing of it outlives the run
    # holding our stdout open (ctest waits for that).
    ( exec </dev/null >/dev/null 2>&1
      end=$((SECONDS + timeout_s))
      while [ "$SECONDS" -lt "$end" ]; do sleep 1; done
      : > "$rundir/timed-out"; kill -TERM -- "-$guest_pid"
      sleep 3; kill -KILL -- "-$guest_pid" ) &
    watchdog_pid=$!
  fi
}

# Reads the result of a guest run: 0 and sets result_rc when the command ran to the end,
# 1 when the guest never started it (boot failure: another backend may be tried),
# 2 when it started but did not finish.
result_rc=0
read_result() {
  local what="$1"
  if [ -f "$rundir/rc" ]; then
    result_rc="$(cat "$rundir/rc")"
    [[ "$result_rc" =~ ^[0-9]+$ ]] || result_rc=125
    return 0
  fi
  if [ -f "$rundir/timed-out" ]; then
    say "$what: stopped after --timeout $timeout_s s"
    result_rc=124
    return 2
  fi
  if [ -f "$rundir/started" ]; then
    say "$what: the guest stopped before the command finished (console log follows)"
    tail -n 25 "$rundir/console.log" >&2 2>/dev/null || true
    result_rc=125
    return 2
  fi
  return 1
}

show_console() {
  if [ "$verbose" = 1 ] && [ -f "$rundir/console.log" ]; then
    say "guest console log:"
    cat "$rundir/console.log" >&2
  fi
  if [ "$keep" = 1 ]; then say "run directory kept: $rundir"; fi
}

# ---------------------------------------------------------------- UML
uml_bin() { command -v linux.uml 2>/dev/null || { [ -x /usr/bin/linux.uml ] && echo /usr/bin/linux.uml; }; }

uml_check() {
  local b
  b="$(uml_bin)" || { uml_why="linux.uml not found: $install_hint can (package user-mode-linux)"; return 1; }
  compgen -G "/usr/lib/uml/modules/*/kernel/drivers/net/can/vcan.ko" >/dev/null \
    || { uml_why="no vcan.ko under /usr/lib/uml/modules: $install_hint can (package user-mode-linux)"; return 1; }
  command -v ip >/dev/null 2>&1 \
    || { uml_why="no 'ip' command: $install_hint can (package iproute2)"; return 1; }
  command -v insmod >/dev/null 2>&1 \
    || { uml_why="no 'insmod' command: $install_hint can (package kmod)"; return 1; }
  uml_exe="$b"
}

# prune KEEP FILES...: removes cached builds of older sources, never KEEP (which another
# run may have just built).
prune() {
  local keep="$1" f; shift
  for f in "$@"; do [ -f "$f" ] && [ "$f" != "$keep" ] && rm -f "$f"; done
  return 0
}

# The XSAVE shim (scripts/vcan/uml-xstate-shim.c), compiled once per source version.
uml_shim() {
  local src="$vdir/uml-xstate-shim.c" sum out cc
  sum="$(cksum < "$src" | cut -d' ' -f1)"
  out="$cache/uml-xstate-shim-$sum.so"
  if [ ! -f "$out" ]; then
    cc="$(command -v "${CC:-cc}" || command -v gcc || true)"
    if [ -z "$cc" ]; then
      say "no C compiler to build the UML XSAVE shim (needed on CPUs with AMX): $install_hint host (package gcc)"
      return 1
    fi
    mkdir -p "$cache"
    prune "$out" "$cache/uml-xstate-shim-"*.so
    if ! "$cc" -shared -fPIC -O2 -o "$out.tmp.$$" "$src" -ldl >&2; then
      rm -f "$out.tmp.$$"
      say "could not build the UML XSAVE shim with $cc; trying UML without it"
      return 1
    fi
    mv "$out.tmp.$$" "$out"
  fi
  echo "$out"
}

run_uml() {   # returns like read_result
  local shim="" preload=()
  shim="$(uml_shim)" && preload=(env "LD_PRELOAD=$shim")
  new_rundir uml "$@"
  local extra=() raw raw_out raw_err
  read -r -a extra <<< "${VCAN_RUN_KERNEL_ARGS:-}"
  raw_flag 1; raw_out=$raw
  raw_flag 2; raw_err=$raw
  # shellcheck disable=SC2054  # the commas belong to UML's channel syntax
  local kargs=(mem="$mem" rootfstype=hostfs rootflags=/ rw init="$rundir/init" quiet
               con=null ssl=null con0=null,fd:3 con1=null,fd:1 con2=null,fd:2
               uml_dir="$rundir/uml" umid=vcan-run
               VCAN_RUN_DIR="$rundir" VCAN_RUN_OUT=/dev/tty1 VCAN_RUN_ERR=/dev/tty2
               VCAN_RUN_RAW_OUT="$raw_out" VCAN_RUN_RAW_ERR="$raw_err"
               VCAN_RUN_IFACES="$(iface_list)" "${extra[@]}")
  # UML puts a terminal on fd 1/2 into raw mode while it runs; put it back even if killed.
  if [ -t 1 ]; then tty_fd=1; fi
  if [ -t "$tty_fd" ]; then saved_tty="$(stty -g <&"$tty_fd" 2>/dev/null || true)"; fi
  "${preload[@]}" setsid "$uml_exe" "${kargs[@]}" </dev/null 3>"$rundir/console.log" &
  guest_pid=$!
  start_watchdog
  wait "$guest_pid" 2>/dev/null   # (no "Aborted" job notice from bash when UML panics)
  kill -KILL -- "-$guest_pid" 2>/dev/null || true
  guest_pid=""
  show_console
  read_result uml
}

# ---------------------------------------------------------------- QEMU
qemu_check() {
  qemu_exe="$(command -v qemu-system-x86_64 2>/dev/null)" \
    || { qemu_why="qemu-system-x86_64 not found: $install_hint can-qemu (package qemu-system-x86)"; return 1; }
  qemu_kver=""
  local v
  for v in $(ls -1 /lib/modules 2>/dev/null | sort -V -r); do
    if [ -f "/boot/vmlinuz-$v" ] && [ -f "/lib/modules/$v/modules.dep" ] \
       && compgen -G "/lib/modules/$v/kernel/drivers/net/can/vcan.ko*" >/dev/null \
       && compgen -G "/lib/modules/$v/kernel/fs/9p/9p.ko*" >/dev/null; then
      qemu_kver="$v"; break
    fi
  done
  [ -n "$qemu_kver" ] \
    || { qemu_why="no Debian kernel with vcan and 9p modules in /boot and /lib/modules: $install_hint can-qemu (package linux-image-amd64)"; return 1; }
  [ -r "/boot/vmlinuz-$qemu_kver" ] \
    || { qemu_why="/boot/vmlinuz-$qemu_kver is not readable (run as root)"; return 1; }
  qemu_busybox=""
  for v in /bin/busybox /usr/bin/busybox; do
    if [ -x "$v" ] && ! ldd "$v" >/dev/null 2>&1; then qemu_busybox="$v"; break; fi
  done
  [ -n "$qemu_busybox" ] \
    || { qemu_why="no static busybox: $install_hint can-qemu (package busybox-static)"; return 1; }
  command -v cpio >/dev/null 2>&1 \
    || { qemu_why="no cpio: $install_hint can-qemu (package cpio)"; return 1; }
}

# A small initramfs: static busybox, the virtio/9p modules, /init = qemu-initramfs-init.sh.
qemu_initramfs() {
  local sum out tmp m n=0
  local mods=(virtio_pci virtio_console 9pnet_virtio 9p)
  sum="$({ echo "${mods[*]}"; cat "$vdir/qemu-initramfs-init.sh" "$qemu_busybox"; } | cksum | cut -d' ' -f1)"
  out="$cache/qemu-initramfs-$qemu_kver-$sum.cpio.gz"
  if [ ! -f "$out" ]; then
    mkdir -p "$cache"
    prune "$out" "$cache/qemu-initramfs-$qemu_kver-"*.cpio.gz
    tmp="$(mktemp -d)"
    mkdir -p "$tmp/bin" "$tmp/modules" "$tmp/proc" "$tmp/sys" "$tmp/dev" "$tmp/newroot"
    cp "$qemu_busybox" "$tmp/bin/busybox"
    cp "$vdir/qemu-initramfs-init.sh" "$tmp/init"
    chmod 755 "$tmp/init" "$tmp/bin/busybox"
    : > "$tmp/modules/order"
    # Module files in load order (built-in ones print as "builtin ...": skipped).
    while read -r m; do
      n=$((n + 1))
      case "$m" in
        *.ko) cp "$m" "$tmp/modules/$n.ko"; echo "$n.ko" >> "$tmp/modules/order" ;;
        *.ko.xz) xz -dc "$m" > "$tmp/modules/$n.ko"; echo "$n.ko" >> "$tmp/modules/order" ;;
        *.ko.zst) zstd -qdc "$m" > "$tmp/modules/$n.ko"; echo "$n.ko" >> "$tmp/modules/order" ;;
      esac
    done < <(modprobe -S "$qemu_kver" --show-depends -a "${mods[@]}" 2>/dev/null \
             | awk '$1 == "insmod" { print $2 }' | awk '!seen[$0]++')
    (cd "$tmp" && find . | cpio -o -H newc --quiet | gzip -1) > "$out.tmp.$$"
    mv "$out.tmp.$$" "$out"
    rm -rf "$tmp"
  fi
  echo "$out"
}

# KVM is tried first when /dev/kvm is usable, but nested KVM can hang before the kernel
# prints anything (seen on the build machines): when the command has not started within
# VCAN_RUN_KVM_DEADLINE seconds (default 20) the guest is stopped, the host is remembered
# as "KVM does not boot" and TCG is used. VCAN_RUN_QEMU_ACCEL=kvm|tcg forces one.
kvm_stamp() { echo "$cache/kvm-does-not-boot-$(uname -r)"; }
qemu_accel() {
  case "${VCAN_RUN_QEMU_ACCEL:-auto}" in
    kvm) echo kvm; return ;;
    tcg) echo tcg; return ;;
  esac
  if [ -r /dev/kvm ] && [ -w /dev/kvm ] && [ ! -f "$(kvm_stamp)" ]; then echo kvm; else echo tcg; fi
}

run_qemu() {
  local accel st
  accel="$(qemu_accel)"
  st=0; run_qemu_once "$accel" "$@" || st=$?
  if [ "$st" = 4 ]; then
    say "qemu: KVM did not boot within ${VCAN_RUN_KVM_DEADLINE:-20} s here; using TCG (remembered in $(kvm_stamp))"
    mkdir -p "$cache" && : > "$(kvm_stamp)"
    rm -rf "$rundir"; rundir=""
    st=0; run_qemu_once tcg "$@" || st=$?
  fi
  return "$st"
}

# Lets the output cats finish: a cat still blocked in open() (QEMU never opened its FIFO)
# gets a writer that closes at once; then both see end-of-file.
release_fifos() {
  local f
  for f in "$rundir/out" "$rundir/err"; do
    { exec 7<>"$f"; exec 7>&-; } 2>/dev/null || true
  done
  wait "$@" 2>/dev/null || true
}

run_qemu_once() {   # run_qemu_once kvm|tcg COMMAND...; as read_result, or 4: KVM hung
  local initrd accel="$1" cpu=max smp=1 model=none
  shift
  initrd="$(qemu_initramfs)" || { say "qemu: could not build the initramfs"; return 1; }
  smp="$(nproc 2>/dev/null || echo 1)"; [ "$smp" -le 2 ] || smp=2
  is_root && model=passthrough
  new_rundir qemu "$@"
  echo "$accel" > "$rundir/accel"
  # QEMU writes the guest's stdout/stderr into FIFOs that cats copy to our own fds: QEMU
  # opening /proc/self/fd/1 itself would not share our file offset when stdout is a file.
  mkfifo "$rundir/out" "$rundir/err"
  cat "$rundir/out" & local cat1=$!
  cat "$rundir/err" >&2 & local cat2=$!
  local append
  append="console=ttyS0 panic=-1 quiet VCAN_RUN_DIR=$rundir VCAN_RUN_OUT=/dev/hvc0 VCAN_RUN_ERR=/dev/hvc1 VCAN_RUN_RAW_OUT=1 VCAN_RUN_RAW_ERR=1 VCAN_RUN_IFACES=$(iface_list) ${VCAN_RUN_KERNEL_ARGS:-}"
  setsid "$qemu_exe" -nodefaults -no-user-config -nographic -no-reboot -monitor none \
    -M pc -accel "$accel" -cpu "$cpu" -smp "$smp" -m "$mem" \
    -kernel "/boot/vmlinuz-$qemu_kver" -initrd "$initrd" -append "$append" \
    -fsdev "local,id=hostroot,path=/,security_model=$model,multidevs=remap" \
    -device virtio-9p-pci,fsdev=hostroot,mount_tag=hostroot \
    -chardev "file,id=con,path=$rundir/console.log" -serial chardev:con \
    -device virtio-serial-pci \
    -chardev "file,id=so,path=$rundir/out" -device virtconsole,chardev=so \
    -chardev "file,id=se,path=$rundir/err" -device virtconsole,chardev=se \
    </dev/null 2>"$rundir/qemu.err" &
  guest_pid=$!
  start_watchdog
  if [ "$accel" = kvm ] && [ "${VCAN_RUN_QEMU_ACCEL:-auto}" = auto ]; then
    local waited=0
    while kill -0 "$guest_pid" 2>/dev/null && [ ! -f "$rundir/started" ] \
          && [ "$waited" -lt "$(( ${VCAN_RUN_KVM_DEADLINE:-20} * 10 ))" ]; do
      sleep 0.1; waited=$((waited + 1))
    done
    if kill -0 "$guest_pid" 2>/dev/null && [ ! -f "$rundir/started" ]; then
      kill -KILL -- "-$guest_pid" 2>/dev/null
      wait "$guest_pid" 2>/dev/null
      guest_pid=""
      if [ -n "$watchdog_pid" ]; then kill "$watchdog_pid" 2>/dev/null; watchdog_pid=""; fi
      release_fifos "$cat1" "$cat2"
      return 4
    fi
  fi
  wait "$guest_pid" 2>/dev/null
  local qrc=$?
  kill -KILL -- "-$guest_pid" 2>/dev/null || true
  guest_pid=""
  release_fifos "$cat1" "$cat2"
  show_console
  if [ ! -f "$rundir/started" ] && [ -s "$rundir/qemu.err" ]; then
    say "qemu (exit $qrc): $(head -n 3 "$rundir/qemu.err")"
  fi
  read_result qemu
}

# ---------------------------------------------------------------- choose and run
finish() {   # after a guest run that ended with read_result status $1
  if [ "$probe" = 1 ]; then
    if [ "$1" = 0 ] && [ "$result_rc" = 0 ]; then say "probe: $2 works"; exit 0; fi
    say "probe: $2 does not work"; exit 125
  fi
  exit "$result_rc"
}

guest() {   # guest uml|qemu COMMAND...: 0..2 as read_result; 3 when not installed
  local b="$1" st t0 t1
  shift
  if [ "$b" = uml ]; then uml_check || { say "uml: $uml_why"; return 3; }
  else qemu_check || { say "qemu: $qemu_why"; return 3; }; fi
  if [ "$b" = uml ]; then
    say "backend uml ($uml_exe $("$uml_exe" --version 2>/dev/null | head -n1), ${ifaces[*]} inside)"
  else
    local how=TCG
    [ "$(qemu_accel)" = kvm ] && how="KVM, or TCG if KVM does not boot"
    say "backend qemu ($qemu_exe, kernel $qemu_kver, $how, ${ifaces[*]} inside)"
  fi
  t0="$(date +%s.%N)"
  st=0
  if [ "$b" = uml ]; then run_uml "$@" || st=$?; else run_qemu "$@" || st=$?; fi
  t1="$(date +%s.%N)"
  if [ "$verbose" = 1 ]; then say "$b: $(awk -v a="$t0" -v b="$t1" 'BEGIN{printf "%.1f", b-a}') s in all"; fi
  if [ "$st" = 1 ]; then
    say "$b: the guest did not start the command (boot failed); console log tail:"
    grep -v '^ *\[<' "$rundir/console.log" 2>/dev/null | tail -n 8 >&2 || true
    [ "$keep" = 1 ] || rm -rf "$rundir"
    rundir=""
  fi
  return "$st"
}

case "$backend" in
  host)
    host_ready || die "the host kernel has no vcan (or cannot create ${ifaces[*]} without root): use --backend uml or qemu"
    run_host "$@" ;;
  uml|qemu)
    st=0; guest "$backend" "$@" || st=$?
    [ "$st" -le 2 ] || die "backend $backend is not available"
    [ "$st" != 1 ] || die "backend $backend did not boot"
    finish "$st" "$backend" ;;
  auto)
    if host_ready; then
      if [ "$probe" = 1 ]; then say "probe: host works (kernel $(uname -r))"; exit 0; fi
      run_host "$@"
    fi
    for b in uml qemu; do
      st=0; guest "$b" "$@" || st=$?
      # 1 (did not boot) and 3 (not installed): the command has not run, try the next.
      if [ "$st" = 0 ] || [ "$st" = 2 ]; then finish "$st" "$b"; fi
    done
    die "no backend could run the command: the host kernel has no vcan, and neither User-Mode Linux ($install_hint can) nor QEMU ($install_hint can-qemu) worked" ;;
esac
