# Phase timing for the test and CI scripts (sourced): `phase NAME` closes the phase before it,
# prints its seconds, and opens NAME; `phases_summary` closes the last one and prints every
# phase with its seconds, so a slow phase shows in every log.
_phase_names=()
_phase_secs=()
_phase_current=""
_phase_start=$SECONDS

_phase_close() {
    if [ -n "$_phase_current" ]; then
        local took=$((SECONDS - _phase_start))
        _phase_names+=("$_phase_current")
        _phase_secs+=("$took")
        echo "-- $_phase_current: ${took} s"
    fi
}

phase() {
    _phase_close
    _phase_current=$1
    _phase_start=$SECONDS
    echo "== $1"
}

phases_summary() {
    _phase_close
    _phase_current=""
    local i total=0
    echo "== seconds per phase (${1:-this run})"
    for i in "${!_phase_names[@]}"; do
        printf '%6d  %s\n' "${_phase_secs[$i]}" "${_phase_names[$i]}"
        total=$((total + _phase_secs[i]))
    done
    printf '%6d  total\n' "$total"
}
