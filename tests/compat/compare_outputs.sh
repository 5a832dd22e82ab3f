#!/usr/bin/env bash
# Runs examples/published_api.cpp built against the compatibility header ($1) and against the oracle of the
# published semantics ($2); each must pass its own physics check (exit 0), and every number they
# print must agree to 1e-9.
set -euo pipefail
compat_output=$("$1")
oracle_output=$("$2")
echo "$compat_output" | tail -n 1
paste -d '\n' <(echo "$compat_output" | grep -v '^#') <(echo "$oracle_output" | grep -v '^#') |
  awk 'NR % 2 == 1 { n = split($0, a, " "); next }
       { m = split($0, b, " ");
         if (m != n) { print "line " NR / 2 ": " n " vs " m " fields"; bad = 1; next }
         for (i = 1; i <= n; ++i) {
           d = a[i] - b[i]; if (d < 0) d = -d;
           if (d > 1e-9) { print "line " NR / 2 " field " i ": " a[i] " vs " b[i]; bad = 1 }
         }
         lines++ }
       END { if (lines < 20) { print "only " lines " lines"; bad = 1 }
             if (!bad) print lines " lines agree to 1e-9"; exit bad }'
