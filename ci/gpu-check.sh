#!/usr/bin/env bash
# The check to run the day a GPU is at hand: every project scene rendered with pathwave's compute BVH and with the
# device's ray queries, rays/s of each and the statistical diff between the two, then the bench's cases side by side.
#
#   bash ci/gpu-check.sh [DEVICE] [--no-bench]
#
# DEVICE is what --device takes (an index or part of a name, `pathwave info --devices`); default: the first device.
# Exit 0 when every scene agrees, 1 when one differs, 2 when the device has no ray queries or a render fails.
set -uo pipefail
cd "$(dirname "$0")/.."
DEVICE=""; BENCH=1
for a in "$@"; do
  case "$a" in
    --no-bench) BENCH=0 ;;
    *) DEVICE="$a" ;;
  esac
done
PW=${PATHWAVE:-target/release/pathwave}
if [ ! -x "$PW" ]; then
  cargo build --release --locked --bin pathwave || exit 2
fi
DEV=()
[ -n "$DEVICE" ] && DEV=(--device "$DEVICE")

"$PW" info --devices
# The device's row must say it has ray queries, else there is nothing to compare.
rows=$("$PW" info --devices)
if [[ "$DEVICE" =~ ^[0-9]+$ ]]; then rows=$(grep "^$DEVICE:" <<<"$rows")
elif [ -n "$DEVICE" ]; then rows=$(grep -iF -- "$DEVICE" <<<"$rows" | head -1); fi
[ -z "$DEVICE" ] && rows=$(head -1 <<<"$rows")
if ! grep -q "ray queries: yes" <<<"$rows"; then
  echo "gpu-check: the device has no ray queries; nothing to compare" >&2
  exit 2
fi

OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
SIZE=${SIZE:-512x384}; SPP=${SPP:-64}
status=0
printf '%-24s %14s %14s  %s\n' scene "compute Mr/s" "rq Mr/s" "diff (ray queries against compute)"
for scene in scenes/*.gltf; do
  n=$(basename "$scene" .gltf)
  rates=()
  for t in compute ray-query; do
    seed=1; [ "$t" = ray-query ] && seed=2
    log=$("$PW" render "$scene" "${DEV[@]}" --traversal "$t" --size "$SIZE" --spp "$SPP" --seed "$seed" \
      --film-stats -o "$OUT/$n.$t.exr" 2>&1)
    if [ $? -ne 0 ]; then
      echo "$n: render with --traversal $t failed:"; echo "$log"; status=2; continue 2
    fi
    if [ "$t" = ray-query ] && ! grep -q "(ray queries)" <<<"$log"; then
      echo "$n: ray queries were not used:"; grep -i "warning" <<<"$log"; status=2; continue 2
    fi
    rates+=("$(grep -o '[0-9.]* Mrays/s' <<<"$log" | tail -1 | cut -d' ' -f1)")
  done
  verdict=$("$PW" diff "$OUT/$n.ray-query.exr" "$OUT/$n.compute.exr" 2>&1)
  code=$?
  [ $code -eq 1 ] && [ $status -eq 0 ] && status=1
  [ $code -gt 1 ] && status=2
  printf '%-24s %14s %14s  %s\n' "$n" "${rates[0]}" "${rates[1]}" "$(head -1 <<<"$verdict")"
done

if [ $BENCH -eq 1 ]; then
  "$PW" bench "${DEV[@]}" --traversal auto || status=2
fi
echo "gpu-check: $([ $status -eq 0 ] && echo "every scene agrees" || echo "exit $status")"
exit $status
