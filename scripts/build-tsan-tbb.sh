#!/usr/bin/env bash
# Builds oneTBB instrumented for ThreadSanitizer from Debian's own source package, for the `tsan`
# preset (docs/ARCHITECTURE.md, "Tests"). Debian's libtbb is not instrumented, so TSan reports false races inside
# TBB and in objects handed from one task to another; linking this build instead removes them.
# Run from anywhere (paths are relative to the repository root), as root or with sudo available:
#
#   build/tsan-tbb/src/     the downloaded source package and its unpacked, patched tree
#   build/tsan-tbb/build/   the Ninja build tree (clang, -DTBB_SANITIZE=thread)
#   build/tsan-tbb/prefix/  the install prefix that the tsan preset's CMAKE_PREFIX_PATH names
#   build/tsan-tbb/stamp    source version, compiler and flags of what the prefix holds
#
# Cached: when the prefix holds TBBConfig.cmake and the stamp records the source version behind
# Debian's libtbb-dev, the same compiler and the same flags, it does nothing. Otherwise it installs
# what it needs (dpkg-dev, clang, cmake, ninja-build), adds a deb-src entry for the Debian archive
# the machine already uses unless one is configured, fetches the source (no root needed) and
# builds it: about 15 s on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."

readonly root=build/tsan-tbb
readonly src_dir=$root/src
readonly build_dir=$root/build
readonly prefix=$root/prefix
readonly stamp=$root/stamp
readonly config=$prefix/lib/cmake/TBB/TBBConfig.cmake
readonly deb_src_sources=/etc/apt/sources.list.d/progiso-deb-src.sources
readonly deb_src_list=/etc/apt/sources.list.d/progiso-deb-src.list
readonly packages=(dpkg-dev clang clang-14 libclang-rt-14-dev cmake ninja-build)
# The library alone: RelWithDebInfo keeps TSan's stacks readable; TBB_STRICT=OFF drops oneTBB's
# own warnings-as-errors, meant for its developers; an explicit libdir fixes the config path.
readonly tbb_flags=(-DCMAKE_BUILD_TYPE=RelWithDebInfo -DTBB_SANITIZE=thread -DTBB_TEST=OFF
                    -DTBB_EXAMPLES=OFF -DTBB_STRICT=OFF -DCMAKE_INSTALL_LIBDIR=lib)

sudo_cmd=()
[ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
apt_user_opts=()
# As root apt drops to the _apt user to download, which cannot write into our build tree.
[ "$(id -u)" -ne 0 ] || apt_user_opts=(-o APT::Sandbox::User=root)

log() { echo "build-tsan-tbb: $*"; }

# Runs "$@" and prints how long it took.
step() {
  local name=$1 t0=$EPOCHREALTIME
  shift
  log "-- $name"
  "$@"
  log "-- $name: $(awk -v a="$t0" -v b="$EPOCHREALTIME" 'BEGIN { printf "%.1f s", b - a }')"
}

# The source version behind the libtbb-dev that Debian installs for the ordinary builds, so that
# the instrumented library matches it (a binNMU names its source version in parentheses).
wanted_version() {
  { apt-cache show --no-all-versions libtbb-dev 2>/dev/null || true; } | awk '
    /^Version:/ { v = $2 }
    /^Source:/ && $3 ~ /^\(/ { s = $3; gsub(/[()]/, "", s) }
    END { print (s != "" ? s : v) }'
}

# The newest onetbb source version in apt's source indices; empty without a deb-src entry.
indexed_source_version() {
  { apt-cache showsrc --only-source onetbb 2>/dev/null || true; } |
    awk '/^Version:/ { print $2 }' | sort -V | tail -n 1
}

has_source_version() {
  { apt-cache showsrc --only-source onetbb 2>/dev/null || true; } |
    awk -v want="$1" '/^Version:/ && $2 == want { found = 1 } END { exit !found }'
}

compiler_id() {
  if command -v clang++ >/dev/null; then clang++ --version | head -n 1; else echo none; fi
}

stamp_text() {
  printf 'onetbb %s\ncompiler %s\nflags %s\n' "$1" "$(compiler_id)" "${tbb_flags[*]}"
}

ensure_packages() {
  local missing=() p
  for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" ||
      missing+=("$p")
  done
  if [ ${#missing[@]} -eq 0 ]; then
    log "all of ${packages[*]} present"
    return
  fi
  log "installing ${missing[*]}"
  "${sudo_cmd[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends \
    "${missing[@]}"
}

# True when apt already has an enabled deb-src entry, ours or the machine's own.
deb_src_configured() {
  local f
  for f in /etc/apt/sources.list /etc/apt/sources.list.d/*.list; do
    [ -f "$f" ] && grep -Eq '^[[:space:]]*deb-src[[:space:]]' "$f" && return 0
  done
  for f in /etc/apt/sources.list.d/*.sources; do
    [ -f "$f" ] || continue
    awk 'function end() { if (src && enabled) found = 1; src = 0; enabled = 1 }
         BEGIN { enabled = 1 }
         /^[[:space:]]*$/ { end(); next }
         tolower($1) == "types:" && / deb-src( |$)/ { src = 1 }
         tolower($1) == "enabled:" && tolower($2) == "no" { enabled = 0 }
         END { end(); exit !found }' "$f" && return 0
  done
  return 1
}

# deb822 stanzas of Types: deb-src with the URIs, Suites, Components and Signed-By (continuation
# lines included) of each enabled Types: deb stanza in the file given.
deb822_sources_for() {
  awk '
    function flush() {
      if (is_deb && enabled && body != "") printf "%sTypes: deb-src\n%s", (n++ ? "\n" : ""), body
      body = ""; is_deb = 0; enabled = 1; keep = 0
    }
    BEGIN { enabled = 1 }
    /^[[:space:]]*$/ { flush(); next }
    /^#/ { next }
    /^[ \t]/ { if (keep) body = body $0 "\n"; next }
    {
      field = tolower($1)
      keep = 0
      if (field == "types:") is_deb = ($0 ~ /[: \t]deb([ \t]|$)/)
      else if (field == "enabled:") enabled = (tolower($2) != "no")
      else if (field == "uris:" || field == "suites:" || field == "components:" ||
               field == "signed-by:") { keep = 1; body = body $0 "\n" }
    }
    END { flush() }' "$1"
}

add_deb_src() {
  local header="# Added by progiso's scripts/build-tsan-tbb.sh: Debian's source packages, for the
# oneTBB that the tsan preset builds instrumented. Safe to remove."
  if [ -f /etc/apt/sources.list.d/debian.sources ]; then
    local body
    body=$(deb822_sources_for /etc/apt/sources.list.d/debian.sources)
    [ -n "$body" ] || { log "no enabled Types: deb stanza in debian.sources"; return 1; }
    printf '%s\n%s\n' "$header" "$body" | "${sudo_cmd[@]}" tee "$deb_src_sources" >/dev/null
    log "added $deb_src_sources:"
  elif [ -f /etc/apt/sources.list ]; then
    local body
    body=$(sed -nE 's/^[[:space:]]*deb[[:space:]]/deb-src /p' /etc/apt/sources.list)
    [ -n "$body" ] || { log "no deb line in /etc/apt/sources.list"; return 1; }
    printf '%s\n%s\n' "$header" "$body" | "${sudo_cmd[@]}" tee "$deb_src_list" >/dev/null
    log "added $deb_src_list:"
  else
    log "neither debian.sources nor sources.list found under /etc/apt"
    return 1
  fi
  sed 's/^/    /' "$deb_src_sources" "$deb_src_list" 2>/dev/null || true
}

apt_update() { "${sudo_cmd[@]}" apt-get update -qq; }

# Makes apt's source indices list onetbb $version (or, with no version wanted, any onetbb).
ensure_source_index() {
  if [ -n "$version" ] && has_source_version "$version"; then
    log "apt already indexes onetbb $version source"
    return
  fi
  local added=0
  if [ ! -f "$deb_src_sources" ] && [ ! -f "$deb_src_list" ] && ! deb_src_configured; then
    add_deb_src
    added=1
  fi
  step "apt-get update" apt_update
  [ -n "$version" ] || version=$(wanted_version)
  [ -n "$version" ] || version=$(indexed_source_version)
  if [ -n "$version" ] && has_source_version "$version"; then return; fi
  if [ "$added" -eq 0 ] && [ ! -f "$deb_src_sources" ] && [ ! -f "$deb_src_list" ]; then
    # The machine's own deb-src entries do not carry onetbb: add Debian's beside them.
    add_deb_src
    step "apt-get update" apt_update
    [ -n "$version" ] || version=$(indexed_source_version)
    if [ -n "$version" ] && has_source_version "$version"; then return; fi
  fi
  log "apt lists no onetbb ${version:-} source package; check the deb-src entries"
  return 1
}

fetch_source() {
  local dsc=$src_dir/onetbb_${version#*:}.dsc
  mkdir -p "$src_dir"
  if [ -f "$dsc" ]; then
    log "reusing downloaded $dsc"
  else
    rm -f "$src_dir"/onetbb_*
    (cd "$src_dir" && apt-get "${apt_user_opts[@]}" source --download-only -qq "onetbb=$version")
  fi
  rm -rf "$src_dir/onetbb"
  log "unpacking; apt has checked the files against the signed archive index, so a gpgv" \
    "warning about the uploader's key (in debian-keyring, not installed) is harmless"
  dpkg-source -x "$dsc" "$src_dir/onetbb"
}

configure_tbb() {
  rm -rf "$build_dir" "$prefix"
  cmake -S "$src_dir/onetbb" -B "$build_dir" -G Ninja -DCMAKE_CXX_COMPILER=clang++ \
    -DCMAKE_C_COMPILER=clang "${tbb_flags[@]}" -DCMAKE_INSTALL_PREFIX="$PWD/$prefix" >/dev/null
}

build_tbb() { cmake --build "$build_dir"; }

install_tbb() { cmake --install "$build_dir" >/dev/null; }

# ---- cached? --------------------------------------------------------------------------------
t_start=$EPOCHREALTIME
version=$(wanted_version)
if [ -f "$config" ] && [ -f "$stamp" ]; then
  recorded=$(sed -n 's/^onetbb //p' "$stamp")
  if [ -z "$version" ]; then
    log "apt knows no libtbb-dev version (no package lists); trusting the stamp's $recorded"
    version=$recorded
  fi
  if [ "$(cat "$stamp")" = "$(stamp_text "$version")" ]; then
    log "up to date, nothing to do: oneTBB $version (TSan) in $prefix" \
      "($(awk -v a="$t_start" -v b="$EPOCHREALTIME" 'BEGIN { printf "%.1f s", b - a }'))"
    exit 0
  fi
  log "stale build ($recorded, wanted ${version:-?}, or compiler/flags changed): rebuilding"
fi

# ---- build ----------------------------------------------------------------------------------
rm -f "$stamp"
step "packages" ensure_packages
step "source index" ensure_source_index
log "oneTBB source version $version"
step "fetch and unpack source" fetch_source
step "configure (clang, TBB_SANITIZE=thread)" configure_tbb
step "build" build_tbb
step "install" install_tbb
[ -f "$config" ] || { log "install did not produce $config"; exit 1; }
stamp_text "$version" >"$stamp"
log "done: oneTBB $version (TSan) in $prefix, total" \
  "$(awk -v a="$t_start" -v b="$EPOCHREALTIME" 'BEGIN { printf "%.1f s", b - a }')"
