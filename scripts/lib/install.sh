# shellcheck shell=bash
# The install steps of the test scripts (sourced by scripts/check, scripts/slcan-python-can and
# scripts/canvm-run). Each tool is installed alone and only when it is missing, so a machine that
# already has it from another source (Node.js and npm from NodeSource, say) keeps it, and apt is
# never asked for a package that would replace or remove what is there (`--no-remove`).
#
# As root, apt-get runs as it is; otherwise through sudo when sudo is there; otherwise the step
# fails and says which Debian package to install.

install_log() { printf 'install: %s\n' "$*" >&2; }

# as_root COMMAND...: COMMAND as root (directly, or through sudo), or status 127 when neither can be.
as_root() {
  if [ "$(id -u)" = 0 ]; then
    "$@"
  elif command -v sudo >/dev/null; then
    sudo -- "$@"
  else
    return 127
  fi
}

_apt_updated=""
# apt_update_once: the package lists, fetched at most once per run (a fresh machine has none).
apt_update_once() {
  [ -n "$_apt_updated" ] && return 0
  _apt_updated=1
  as_root env DEBIAN_FRONTEND=noninteractive apt-get update -q >/dev/null || true
}

# apt_install PACKAGE: Debian's PACKAGE, alone. Refused (status 1, nothing changed) when apt would
# have to remove a package of the machine to install it; the message names that package.
apt_install() {
  local package=$1 plan removed
  if [ "$(id -u)" != 0 ] && ! command -v sudo >/dev/null; then
    install_log "cannot install $package: not root and no sudo. Install it (as root: apt-get install $package) and run again"
    return 1
  fi
  apt-cache show "$package" >/dev/null 2>&1 || apt_update_once
  plan=$(apt-get install -s -q --no-install-recommends "$package" 2>&1) || { apt_update_once;
    plan=$(apt-get install -s -q --no-install-recommends "$package" 2>&1); } || {
    install_log "apt cannot install $package:"; printf '%s\n' "$plan" | grep '^E:' >&2; return 1; }
  removed=$(printf '%s\n' "$plan" | awk '/^Remv / {print $2}' | tr '\n' ' ')
  if [ -n "$removed" ]; then
    install_log "not installing Debian's $package: it would remove ${removed}from this machine"
    return 1
  fi
  install_log "Debian package $package"
  if ! plan=$(as_root env DEBIAN_FRONTEND=noninteractive \
    apt-get install -y -q --no-remove --no-install-recommends "$package" 2>&1); then
    printf '%s\n' "$plan" | tail -5 >&2
    install_log "apt-get install $package failed; install it by hand and run again"
    return 1
  fi
}

# need_command COMMAND PACKAGE: install PACKAGE when COMMAND is not found (on PATH or in /usr/sbin).
need_command() {
  local command=$1 package=$2
  command -v "$command" >/dev/null || [ -x "/usr/sbin/$command" ] && return 0
  apt_install "$package"
}

# need_free_space DIR GB: fails, naming DIR and both figures, unless DIR's file system has room for
# GB gigabytes more than DIR already holds (a run that rebuilds in place needs only the difference).
need_free_space() {
  local dir=$1 need_gb=$2 probe=$1 free_kb used_kb=0 short_kb
  while [ ! -e "$probe" ]; do probe=$(dirname "$probe"); done
  free_kb=$(df -Pk "$probe" | awk 'NR == 2 { print $4 }')
  [ -d "$dir" ] && used_kb=$(du -sk "$dir" 2>/dev/null | cut -f1)
  short_kb=$((need_gb * 1024 * 1024 - used_kb - free_kb))
  [ "$short_kb" -le 0 ] && return 0
  install_log "not enough disk space: the run writes about $need_gb GB under $dir; $((free_kb / 1048576)) GB free and $((used_kb / 1048576)) GB already there. Free $(((short_kb + 1048575) / 1048576)) GB more and run again"
  return 1
}

# need_package PACKAGE...: install each PACKAGE that dpkg does not list as installed, one at a time.
need_package() {
  local package
  for package in "$@"; do
    dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q 'install ok installed' && continue
    apt_install "$package" || return 1
  done
}

# need_cargo_tool COMMAND CRATE VERSION [ARG...]: CRATE at VERSION from crates.io (cargo install
# --locked, with ARGs such as --no-default-features) when COMMAND is not found; a COMMAND the
# machine already has is kept as it is. Built outside the workspace, so with the machine's default
# toolchain rather than the one the workspace pins for its own code (a tool may need a newer one).
need_cargo_tool() {
  local command=$1 crate=$2 version=$3
  shift 3
  command -v "$command" >/dev/null && return 0
  install_log "cargo install $crate $version"
  (cd "${TMPDIR:-/tmp}" && cargo install --locked --quiet "$crate" --version "$version" "$@")
}

# need_qemu BINARY PACKAGE: QEMU's BINARY (qemu-system-arm, qemu-system-x86_64) on PATH. From
# Debian's PACKAGE when apt can install it; when that would remove a package of the machine (a
# newer qemu-utils, from backports, breaks Debian 12's qemu-system-common), the two packages are
# unpacked into a cache of the user's instead, their libraries installed from Debian, and that
# copy's bin directory is put first on PATH. QEMU finds its modules (the TCG accelerator) relative
# to its own binary; its ROMs come from Debian's qemu-system-data through a link.
need_qemu() {
  local binary=$1 package=$2 version dir tmp deps
  command -v "$binary" >/dev/null && return 0
  apt-cache show "$package" >/dev/null 2>&1 || apt_update_once
  version=$(apt-cache policy "$package" | awk '/Candidate:/ {print $2}' | tr ':' '_')
  dir=${DNET_TOOLS_DIR:-${XDG_CACHE_HOME:-$HOME/.cache}/dnet-tools}/$package-$version
  if [ ! -x "$dir/usr/bin/$binary" ]; then
    apt_install "$package" && return 0
    install_log "unpacking $package $version and qemu-system-common into $dir instead"
    deps=$(apt-cache depends --no-recommends --no-suggests --no-conflicts --no-breaks --no-replaces \
      --no-enhances "$package" | awk '/Depends: / && $2 !~ /^qemu-system-/ {print $2}' | sort -u)
    # shellcheck disable=SC2086
    need_package $deps qemu-system-data || return 1
    tmp=$(mktemp -d) && chmod 755 "$tmp" || return 1  # readable by apt's own download user
    (cd "$tmp" && apt-get download -q "$package" qemu-system-common >/dev/null 2>&1) || {
      install_log "apt-get download $package qemu-system-common failed"; rm -rf "$tmp"; return 1; }
    mkdir -p "$dir.new" && for deb in "$tmp"/*.deb; do dpkg-deb -x "$deb" "$dir.new" || return 1; done
    mkdir -p "$dir.new/usr/share" && ln -sfn /usr/share/qemu "$dir.new/usr/share/qemu"
    rm -rf "$tmp" "$dir" && mv "$dir.new" "$dir"
  fi
  PATH=$dir/usr/bin:$PATH
  export PATH
  command -v "$binary" >/dev/null
}

# python_venv DIR PACKAGE==VERSION...: a virtual environment at DIR holding exactly these
# distributions (pip installs them only when one is missing or at another version).
python_venv() {
  local dir=$1; shift
  if [ ! -x "$dir/bin/python" ]; then
    python3 -m venv "$dir" 2>/dev/null || { need_package python3-venv && python3 -m venv "$dir"; } || return 1
  fi
  "$dir/bin/python" - "$@" <<'PY' 2>/dev/null && return 0
import sys
from importlib.metadata import version, PackageNotFoundError
for spec in sys.argv[1:]:
    name, wanted = spec.split("==")
    try:
        if version(name) != wanted:
            sys.exit(1)
    except PackageNotFoundError:
        sys.exit(1)
PY
  install_log "Python packages $* in $dir"
  "$dir/bin/pip" install --quiet --disable-pip-version-check "$@"
}

# need_rust_toolchain: the toolchain rust-toolchain.toml pins (its channel), with the components
# and targets that file lists. rustup installs it where it can download; on a machine that cannot
# (no network but the package registries) and whose stable toolchain is that same release, stable
# is linked under the pinned name instead (rustup reads the file at every cargo call and would
# otherwise try to download the pinned toolchain, and fail).
need_rust_toolchain() {
  local channel host home
  channel=$(sed -n 's/^channel *= *"\(.*\)"/\1/p' rust-toolchain.toml)
  host=$(RUSTUP_TOOLCHAIN=stable rustc -vV 2>/dev/null | sed -n 's/^host: //p')
  rustup toolchain list | grep -q "^$channel-$host" && return 0
  if RUSTUP_TOOLCHAIN=stable rustc -V 2>/dev/null | grep -q "^rustc $channel "; then
    home=$(rustup show home)
    install_log "rust toolchain $channel: linked to stable (the same release)"
    ln -s "$home/toolchains/stable-$host" "$home/toolchains/$channel-$host"
    return 0
  fi
  install_log "rustup toolchain install $channel"
  rustup toolchain install "$channel" --profile minimal
}

# need_windows_cross: what scripts/windows-build and scripts/windows-wine need, from Debian: the
# MinGW-w64 C compiler and linker, Debian's Rust compiler with the standard library's source (the
# pinned toolchain's x86_64-pc-windows-gnu standard library cannot be downloaded here), and wine.
need_windows_cross() {
  need_command x86_64-w64-mingw32-gcc gcc-mingw-w64-x86-64 || return 1
  need_package rustc-web rust-web-src wine64 wine
}
