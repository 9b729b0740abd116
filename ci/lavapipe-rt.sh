#!/usr/bin/env bash
# Brings a second lavapipe, Mesa >= 24.1 from the distribution's backports suite (ray queries on the CPU), into
# ~/.cache/pathwave/lavapipe-rt without touching the system's driver, and prints the path of its ICD file.
#
# The suite is reached through the Debian source the machine's apt already uses (its URI and keyring, with the suite
# <codename>-backports), with apt's lists and cache kept in the private folder: nothing of the system's apt state or
# packages changes, so the system's lavapipe keeps running everything else. Idempotent: a second run only prints.
# Usage: ICD=$(bash ci/lavapipe-rt.sh) && VK_DRIVER_FILES=$ICD pathwave info --devices
set -euo pipefail

MIN_VERSION=24.1
DEST="${PATHWAVE_CACHE:-$HOME/.cache/pathwave}/lavapipe-rt"
ICD="$DEST/lvp_icd.json"

if [ -f "$DEST/.installed" ] && [ -f "$ICD" ]; then
  echo "$ICD"
  exit 0
fi

say() { echo "ci/lavapipe-rt.sh: $*" >&2; }

. /etc/os-release
CODENAME="${VERSION_CODENAME:?/etc/os-release names no codename}"
ARCH=$(dpkg --print-architecture)

# The configured source that serves "$CODENAME main": one-line entries (sources.list, *.list) and deb822 stanzas
# (*.sources). Prints "URI<TAB>KEYRING" (the keyring may be empty: apt's trusted keys then apply).
find_source() {
  local f
  for f in /etc/apt/sources.list /etc/apt/sources.list.d/*.list; do
    [ -f "$f" ] || continue
    awk -v suite="$CODENAME" '
      $1 == "deb" {
        key = ""; i = 2
        if ($2 ~ /^\[/) {
          while (i <= NF) {
            if ($i ~ /signed-by=/) { key = $i; sub(/.*signed-by=/, "", key); sub(/\]$/, "", key) }
            if ($i ~ /\]$/) { i++; break }
            i++
          }
        }
        if ($(i + 1) == suite) { for (j = i + 2; j <= NF; j++) if ($j == "main") { print $i "\t" key; exit } }
      }' "$f"
  done
  for f in /etc/apt/sources.list.d/*.sources; do
    [ -f "$f" ] || continue
    awk -v suite="$CODENAME" '
      function flush() {
        if (deb && main && has_suite && uri != "") print uri "\t" key
        deb = 0; main = 0; has_suite = 0; uri = ""; key = ""
      }
      /^[ \t]*$/ { flush(); next }
      /^#/ { next }
      tolower($1) == "types:" { for (j = 2; j <= NF; j++) if ($j == "deb") deb = 1 }
      tolower($1) == "uris:" { uri = $2 }
      tolower($1) == "suites:" { for (j = 2; j <= NF; j++) if ($j == suite) has_suite = 1 }
      tolower($1) == "components:" { for (j = 2; j <= NF; j++) if ($j == "main") main = 1 }
      tolower($1) == "signed-by:" { key = $2 }
      END { flush() }' "$f"
  done
}

SOURCE=$(find_source | head -n 1)
if [ -z "$SOURCE" ]; then
  say "no configured apt source serves $CODENAME main; cannot reach $CODENAME-backports"
  exit 1
fi
URI=${SOURCE%%$'\t'*}
KEY=${SOURCE#*$'\t'}

APT="$DEST/apt"
rm -rf "$DEST"
mkdir -p "$APT/lists/partial" "$APT/cache/archives/partial" "$APT/etc" "$DEST/debs" "$DEST/root"
if [ -n "$KEY" ]; then OPTS="[signed-by=$KEY] "; else OPTS=""; fi
echo "deb ${OPTS}$URI $CODENAME-backports main" > "$APT/etc/sources.list"
APT_OPTS=(
  -o "Dir::Etc::SourceList=$APT/etc/sources.list" -o Dir::Etc::SourceParts=/dev/null
  -o "Dir::State::Lists=$APT/lists" -o "Dir::Cache=$APT/cache" -o "Dir::State::status=/var/lib/dpkg/status"
  -o Debug::NoLocking=1 -q
)
# apt's download sandbox user cannot write into a folder under root's home.
if [ "$(id -u)" -eq 0 ]; then APT_OPTS+=(-o APT::Sandbox::User=root); fi
say "reading $CODENAME-backports through the configured source"
apt-get "${APT_OPTS[@]}" update >&2

VERSION=$(apt-cache "${APT_OPTS[@]}" show "mesa-vulkan-drivers:$ARCH" 2>/dev/null | awk '$1 == "Version:" { print $2; exit }')
if [ -z "$VERSION" ] || dpkg --compare-versions "$VERSION" lt "$MIN_VERSION"; then
  say "$CODENAME-backports has mesa-vulkan-drivers ${VERSION:-(none)}; ray queries on lavapipe need $MIN_VERSION or later"
  exit 1
fi
say "fetching mesa-vulkan-drivers $VERSION"
(cd "$DEST/debs" && apt-get "${APT_OPTS[@]}" download "mesa-vulkan-drivers:$ARCH=$VERSION" >&2)
for deb in "$DEST"/debs/*.deb; do dpkg-deb -x "$deb" "$DEST/root"; done
# Keep lavapipe only (the package also holds the GPU drivers and layers): 75 MB down to a third.
find "$DEST/root" -name 'libvulkan_*.so' ! -name libvulkan_lvp.so -delete
find "$DEST/root" -name 'libVkLayer_*.so' -delete
rm -rf "$DEST/debs" "$APT"

LIB=$(find "$DEST/root" -name libvulkan_lvp.so -print -quit)
if [ -z "$LIB" ]; then
  say "mesa-vulkan-drivers $VERSION holds no libvulkan_lvp.so"
  exit 1
fi
# Only the package itself: the rest of what it depends on is the same as the system's (libLLVM-15, libc), and the
# newer libdrm it names is not needed by lavapipe, which opens no DRM device (tried with bookworm's 2.4.114).
# The package's own ICD file names the library relative to the system's search path; this one names the private copy.
API=$(sed -n 's/.*"api_version": *"\([0-9.]*\)".*/\1/p' "$(find "$DEST/root" -name 'lvp_icd*.json' -print -quit)")
printf '{\n    "file_format_version": "1.0.0",\n    "ICD": {\n        "library_path": "%s",\n        "api_version": "%s"\n    }\n}\n' \
  "$LIB" "${API:-1.3.0}" > "$ICD"
echo "$VERSION" > "$DEST/.installed"
say "lavapipe $VERSION in $DEST"
echo "$ICD"
