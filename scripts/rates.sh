#!/usr/bin/env bash
# Generation rates of every task variant from the bundled source demos of each style, beside the
# paper's (Table "Data Generation Rates"), as a Markdown table on stdout.
#
#   bash scripts/rates.sh [--attempts N] [--styles "careful human"] [--workers W] [--only "square threading"] [--out DIR]
#
# `careful` is the careful scripted demos (`core/sim/data/<task>_D0_source.hdf5`), `human` the
# human-style ones (`<task>_D0_human.hdf5`, `mimicgen demos --style human`). Every run is
# `mimicgen generate --task T --variant V --source FILE --num-demos N --seed 1`, its report kept in
# DIR (default /tmp/mimicgen-rates); a run whose report is already there is not run again.
# MIMICGEN (default: the debug build in $CARGO_TARGET_DIR) is the binary.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
attempts=1000 styles="careful human" workers=2 only="" out=/tmp/mimicgen-rates
while [[ $# -gt 0 ]]; do
  case "$1" in
    --attempts) attempts="$2"; shift 2 ;;
    --styles) styles="$2"; shift 2 ;;
    --workers) workers="$2"; shift 2 ;;
    --only) only="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    -h|--help) sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "rates.sh: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done
export MIMICGEN_CACHE="${MIMICGEN_CACHE:-$HOME/.cache/mimicgen}"
bin="${MIMICGEN:-${CARGO_TARGET_DIR:-$MIMICGEN_CACHE/target}/debug/mimicgen}"
mkdir -p "$out"
# task variant paper-rate (the paper's table), the D0s first
variants="stack D0 94.3
stack_three D0 71.3
square D0 73.7
threading D0 51.0
coffee D0 78.2
three_piece_assembly D0 35.6
hammer_cleanup D0 47.6
mug_cleanup D0 29.5
kitchen D0 100.0
nut_assembly D0 50.0
pick_place D0 32.7
coffee_preparation D0 53.2
nut_bolt_assembly D0 66.0
gear_assembly D0 46.9
frame_assembly D0 45.3
mobile_kitchen D0 20.7
stack D1 90.0
stack_three D1 68.9
square D1 48.9
threading D1 39.2
coffee D1 63.5
three_piece_assembly D1 35.5
hammer_cleanup D1 20.4
mug_cleanup D1 17.0
kitchen D1 42.7
coffee_preparation D1 36.1
nut_bolt_assembly D1 59.4
gear_assembly D1 8.2
frame_assembly D1 32.7
square D2 31.8
threading D2 21.6
coffee D2 27.7
three_piece_assembly D2 31.3
nut_bolt_assembly D2 47.6
gear_assembly D2 7.1
frame_assembly D2 28.9"
header="| task | variant |"
rule="|---|---|"
for style in $styles; do header+=" $style |"; rule+="---|"; done
echo "$header paper |"
echo "$rule---|"
while read -r task variant paper; do
  [[ -z "$only" || " $only " == *" $task "* ]] || continue
  row="| $task | $variant |"
  for style in $styles; do
    suffix="$style"; [[ "$style" == careful ]] && suffix=source
    source="core/sim/data/${task}_D0_${suffix}.hdf5"
    report="$out/${task}_${variant}_${style}.json"
    if [[ ! -f "$report" ]]; then
      "$bin" generate --task "$task" --variant "$variant" --source "$source" --num-demos "$attempts" \
        --seed 1 --workers "$workers" --overwrite --out "$out/${task}_${variant}_${style}.hdf5" >/dev/null 2>"$out/${task}_${variant}_${style}.log"
      rm -f "$out/${task}_${variant}_${style}.hdf5"
    fi
    row+=" $(python3 -c 'import json,sys; r=json.load(open(sys.argv[1])); print("%.1f %% of %d" % (100*r["generation_rate"], r["attempts"]))' "$report") |"
  done
  echo "$row $paper % |"
done <<< "$variants"
