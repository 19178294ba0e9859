#!/bin/busybox sh
# /init of the small initramfs that scripts/vcan-run.sh builds for its QEMU backend:
# loads the virtio/9p modules listed in /modules/order, mounts the host's root (shared by
# QEMU as virtio-9p tag "hostroot") and hands over to scripts/vcan/guest-init.sh there.
# The command's stdout and stderr leave through virtio consoles hvc0 and hvc1 (an emulated
# UART under TCG lost the first bytes of writes that followed a pause).
/bin/busybox mkdir -p /proc /sys /dev /newroot
/bin/busybox mount -t proc proc /proc
/bin/busybox mount -t devtmpfs devtmpfs /dev
while read -r m; do
  /bin/busybox insmod "/modules/$m" 2>/dev/null
done < /modules/order
if ! /bin/busybox mount -t 9p -o "trans=virtio,version=9p2000.L,msize=262144${VCAN_RUN_9P:+,$VCAN_RUN_9P}" hostroot /newroot; then
  echo "vcan-run initramfs: cannot mount the host root over virtio-9p" > /dev/hvc1
  /bin/busybox sleep 1
  /bin/busybox poweroff -f
fi
/bin/busybox mount --move /dev /newroot/dev
/bin/busybox umount /proc
exec /bin/busybox switch_root /newroot "$VCAN_RUN_DIR/init"
