#!/usr/bin/env bash
# run.sh: weight 0.25 seconds 30
# A batch across nodes on PostgreSQL (server/api/smd_batches.h): two API
# nodes and two worker nodes; 4 targets (circles of radius 0.60 .. 0.85,
# the disk template) submitted to the API node and grouped into a batch
# there.  Each worker's runs last at least a second (a wrapper worker
# sleeps first), so that the worker node w2 is killed (-9) while it runs
# a target (its runs there are held until then): its lease expires and
# the target runs again on w1 (attempt 2); nothing is lost: every target ends successful, the model job runs
# once they all ended (the claim skips it while a member is queued or
# running), on w1, from the members' results copied in from the database
# (members/<id>/), and its model has all 4 members with mode 1 carrying
# >= 95% of the variance (the family has one parameter).  The batch
# document is the same on a second API node (a replica of the database:
# the members' job.json and records mirrored).  A live batch cancelled on
# the other API node: its model job and targets dismissed in the database.
source "$(dirname "$0")/lib.sh"
source "$(dirname "$0")/../lib/cluster.sh"

if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
if ! pg_up; then
    not_ok "PostgreSQL 15 starts (initdb + pg_ctl in $PGDIR)"
    exit 1
fi
RADII="0.60 0.70 0.80 0.85"
for R in $RADII; do
    awk -v R="$R" -f "$WORK/case/sdf.awk" "$BOX" >"$WORK/case/box-$R.sol"
done
cat >"$WORK/slow-worker.sh" <<EOF
#!/bin/sh
sleep 1
exec "$BIN/shapematch-worker" "\$@"
EOF
# w2's runs never end by themselves: it is still running its target when
# it is killed, however slow the machine (a run of a second once ended
# first on a loaded one); the wrapper ends with its node
cat >"$WORK/held-worker.sh" <<'EOF'
#!/bin/sh
while kill -0 "$PPID" 2>/dev/null; do sleep 0.2; done
exit 1
EOF
chmod +x "$WORK/slow-worker.sh" "$WORK/held-worker.sh"
# a lease of 4 s, scaled (2 s once: a node starved for more than 1.3 s on a
# loaded machine lost a lease it held)
LEASE=$((4 * SLOW))
started=1
node api api --workers 1 --lease "$LEASE" || started=0
node api2 api --workers 1 --lease "$LEASE" || started=0
node w1 worker --workers 1 --lease "$LEASE" --worker "$WORK/slow-worker.sh" || started=0
node w2 worker --workers 1 --lease "$LEASE" --worker "$WORK/held-worker.sh" || started=0
if [ "$started" = 1 ] && [ "$(psql_val 'SELECT max(version) FROM smd_schema')" = 3 ]; then
    ok "two API nodes and two worker nodes start; schema version 3"
else
    not_ok "the nodes start" "$(tail -n 3 "$WORK"/*.log)"
    exit 1
fi

on api
ids=()
for R in $RADII; do
    id=$(submit "$DISK" "$BOX" "$WORK/case/box-$R.sol" "$(quick_params 30)")
    [ -n "$id" ] && ids+=("$id")
done
body=$(k=0; for id in "${ids[@]}"; do k=$((k + 1)); echo "{\"job\": \"$id\", \"name\": \"r$k\"}"; done |
    jq -s '{targets: ., model_align: "rigid", template_from: {mode: "mean", round: 1}}')
code=$(hcurl -o "$WORK/batch.out" -w '%{http_code}' -H 'Content-Type: application/json' \
    --data-binary "$body" "$BASE/v1/batches")
B=$(jq -r '.batchID // empty' "$WORK/batch.out")
members=$(psql_val "SELECT cardinality(members) FROM smd_jobs WHERE id = '$B'")
all "4 targets and the batch accepted by the API node; the database holds its members" \
    "${#ids[@]}|=|4" "$code|=|201" "$members|=|4"

# kill w2 while it runs a target
# (grep first: a log line that is not JSON would stop jq)
w2_claimed() { grep -q '"event":"job_claimed"' "${NODE_LOG[w2]}"; }
poll 30 w2_claimed
victim=$(grep '"event":"job_claimed"' "${NODE_LOG[w2]}" | jq -r .job | tail -1)
kill9 w2
if [ -n "$victim" ] && [ "$victim" != "$B" ]; then
    ok "w2 killed (-9) while it ran target $victim"
else
    not_ok "w2 ran a target when killed" "victim '$victim'"
fi

on api
batch_final() {
    case $(hcurl "$BASE/v1/batches/$B" | jq -r .status) in successful | failed | dismissed) return 0 ;; esac
    return 1
}
poll 90 batch_final
doc=$(hcurl "$BASE/v1/batches/$B")
attempt=$(psql_val "SELECT attempt FROM smd_jobs WHERE id = '$victim'")
if jq -e '.status == "successful" and .counts.successful == 4' <<<"$doc" >/dev/null &&
    [ "$attempt" = 2 ]; then
    ok "nothing lost: every target successful (the killed one as attempt 2), the model built"
else
    not_ok "the batch after the kill" "attempt $attempt" "$doc"
fi
model_node=$(grep '"event":"job_claimed"' "${NODE_LOG[w1]}" |
    jq -r --arg b "$B" 'select(.job == $b) | .node' | head -1)
model_started=$(psql_val "SELECT extract(epoch FROM started) FROM smd_jobs WHERE id = '$B'")
last_member=$(psql_val "SELECT max(extract(epoch FROM finished)) FROM smd_jobs WHERE id IN ($(printf "'%s'," "${ids[@]}" | sed 's/,$//'))")
if [ -n "$model_node" ] && awk -v s="$model_started" -v f="$last_member" 'BEGIN { exit !(s >= f) }'; then
    ok "the model job was claimed by w1 after the last target ended"
else
    not_ok "the model job's claim" "node '$model_node' started $model_started last member $last_member"
fi
hcurl "$BASE/v1/batches/$B/model" >"$WORK/model.json"
if jq -e '.summary.members == 4 and .summary.variance_explained[0] >= 0.95' "$WORK/model.json" >/dev/null; then
    ok "its model has the 4 members; mode 1 carries $(jq '.summary.variance_explained[0]' "$WORK/model.json")"
else
    not_ok "the model" "$(head -c 500 "$WORK/model.json")"
fi
same() {
    on api
    local a b
    a=$(hcurl "$BASE/v1/batches/$B" | jq -c '[.status, .counts, [.targets[].status], .templateFrom]')
    on api2
    b=$(hcurl "$BASE/v1/batches/$B" | jq -c '[.status, .counts, [.targets[].status], .templateFrom]')
    echo "api $a api2 $b" >"$WORK/same.txt"
    [ -n "$a" ] && [ "$a" = "$b" ] && jq -e '.[3] == {mode: "mean", round: 1}' <<<"$b" >/dev/null
}
if poll 10 same; then
    ok "the batch document is the same on the other API node (its replica of the database), templateFrom included"
else
    not_ok "the batch on both nodes" "$(cat "$WORK/same.txt")"
fi
# cancel across nodes: two endless targets (one runs on w1), DELETE on
# the other API node: the model job and both targets dismissed everywhere
on api
c1=$(submit "$FINE" "$BOX" "$WORK/case/box-0.60.sol" "$(endless_params)")
c2=$(submit "$FINE" "$BOX" "$WORK/case/box-0.70.sol" "$(endless_params)")
CB=$(hcurl -H 'Content-Type: application/json' --data-binary \
    "{\"targets\": [{\"job\": \"$c1\"}, {\"job\": \"$c2\"}]}" "$BASE/v1/batches" | jq -r '.batchID // empty')
poll 20 state_is "$c1" running
on api2
poll 10 state_in "$CB" accepted
code=$(hcurl -o /dev/null -w '%{http_code}' -X DELETE "$BASE/v1/batches/$CB")
dismissed() {
    local id
    for id in "$CB" "$c1" "$c2"; do
        [ "$(psql_val "SELECT state FROM smd_jobs WHERE id = '$id'")" = dismissed ] || return 1
    done
}
if [ "$code" = 200 ] && poll 20 dismissed; then
    ok "DELETE of a live batch on the other API node: the model job and both targets dismissed in the database"
else
    not_ok "cancel across nodes" "$code $(psql_val "SELECT string_agg(state, ' ') FROM smd_jobs WHERE id IN ('$CB', '$c1', '$c2')")"
fi
if reports_clean; then ok "no sanitizer reports"; else not_ok "sanitizer reports"; fi
echo "1..$n"
