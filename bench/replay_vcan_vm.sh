#!/bin/sh
# Inside the vcan VM (../shared/vcan/run-in-vm.sh): replay the frames bench_replay.py --vm-prepare
# wrote into DIR with dv_pacer and canplayer on vcan0, candump -L recording each run into OUT.
#   bench/replay_vcan_vm.sh DIR OUT DV_PACER
# Then on the host: bench_replay.py --vm-collect OUT (it parses the dumps against the plans).
set -u
DIR=$1 OUT=$2 PACER=$3
for f in "$DIR"/in_*.bin; do
    r=$(basename "$f" .bin); r=${r#in_}
    for who in dv_pacer dv_pacer_fifo canplayer canplayer_g0; do
        candump -L vcan0 > "$OUT/$r.$who.dump" & dump=$!
        sleep 1
        case $who in
            dv_pacer) "$PACER" -i vcan0 < "$f" > /dev/null ;;
            dv_pacer_fifo) "$PACER" -i vcan0 -r 10 < "$f" > /dev/null ;;
            canplayer) canplayer -I "$DIR/in_$r.log" ;;
            canplayer_g0) canplayer -g 0 -I "$DIR/in_$r.log" ;;
        esac
        sleep 1
        kill -INT $dump; wait $dump
    done
done
