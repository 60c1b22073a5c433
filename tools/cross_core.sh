#!/bin/sh
# Cross-compile the SLAM core for a Cortex-M7 (FPv5 double-precision FPU)
# with the core's strict warnings, link one image per filter, and report the
# static RAM (.data + .bss) of each. Fails if anything links a heap function.
#   usage: cross_core.sh <out-dir> <core-dir> <footprint_main.c>
set -eu
out=$1 core=$2 main=$3
CC=${ARM_CC:-arm-none-eabi-gcc}
SIZE=${ARM_SIZE:-arm-none-eabi-size}
NM=${ARM_NM:-arm-none-eabi-nm}
mkdir -p "$out"
cpu="-mcpu=cortex-m7 -mthumb -mfpu=fpv5-d16 -mfloat-abi=hard"
warn="-Wall -Wextra -Wpedantic -Wconversion -Wdouble-promotion -Wshadow -Wstrict-prototypes -Wmissing-prototypes -Wvla -Wundef -Werror"
cflags="$cpu -std=c11 -O2 -ffunction-sections -fdata-sections -DNDEBUG $warn -I$core/include"
objs=""
for src in "$core"/src/*.c; do
  obj="$out/$(basename "$src" .c).o"
  $CC $cflags -c "$src" -o "$obj"
  objs="$objs $obj"
done
# the core objects alone must not reference the heap
if $NM -u $objs | grep -wqE 'malloc|calloc|realloc|free'; then
  echo "cross_core: the core references the heap" >&2; exit 1
fi
report="$out/footprint.txt.tmp"
: > "$report"
for f in FASTSLAM EKFSLAM; do
  elf="$out/footprint_$(echo $f | tr A-Z a-z).elf"
  $CC $cflags -D FOOTPRINT_$f "$main" $objs -o "$elf" \
      --specs=nano.specs --specs=nosys.specs -Wl,--gc-sections -lm
  if $NM "$elf" | grep -wqE '(malloc|_malloc_r|calloc|realloc|free|_free_r)$'; then
    echo "cross_core: $elf links a heap function" >&2; exit 1
  fi
  # Berkeley format: text data bss dec hex filename
  set -- $($SIZE -B "$elf" | tail -n 1)
  printf '%-8s text=%s data=%s bss=%s static_ram=%s bytes\n' "$f" "$1" "$2" "$3" "$(( $2 + $3 ))" >> "$report"
done
mv "$report" "$out/footprint.txt"
cat "$out/footprint.txt"
