#!/usr/bin/python3
"""AttacksSmoke: bench/attacks on the items whose outcome does not depend on timing.

Runs `bench/attacks --only 1,4,5,8,35` (DDS params nested 80 000 deep, non-finite and huge
numbers, DDS client-id hijack and zero id, `simgate check` on the bad configs; issue #35's
POST to a line port, process control from JSON-RPC, a stream around a denied service) against the
build tree and checks, never a timing threshold:
  * it exits 0 and writes its JSON;
  * every item asked for has rows, every row has the four columns and a verdict, and every
    verdict is PASS;
  * the last row is the final check: the same process alive, serving every transport;
  * stdout holds the Markdown table.
Prints one line per check and "N passed, N failed" at the end.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
ITEMS = (1, 4, 5, 8, 35)

passed, failed = 0, 0


def check(ok, what):
    global passed, failed
    if ok:
        passed += 1
    else:
        failed += 1
    print(f"{'ok  ' if ok else 'FAIL'} {what}", flush=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--build-dir", required=True)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "attacks.json")
        r = subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "bench", "attacks"), "--build-dir", args.build_dir,
                            "--only", ",".join(map(str, ITEMS)), "--json", out],
                           capture_output=True, text=True, timeout=240)
        check(r.returncode == 0, f"bench/attacks exits 0 (exit {r.returncode}; stderr tail: "
                                 f"{r.stderr.strip()[-600:]!r})")
        check(os.path.exists(out), "it writes its JSON")
        if not os.path.exists(out):
            return 1
        result = json.load(open(out))
    rows = result.get("rows", [])
    for item in ITEMS:
        mine = [row for row in rows if row["item"].split(".")[0].rstrip("abcdefghi'") == str(item)]
        check(mine, f"item {item} has rows ({len(mine)})")
    for row in rows:
        check(all(row.get(k) for k in ("item", "attack", "now")) and row.get("verdict") == "PASS",
              f"row {row.get('item')}: {row.get('verdict')}: {row.get('attack')}: {row.get('now')}")
    check(rows and rows[-1]["item"] == "end", "the last row is the final check on every transport")
    check("| # | attack | before (issue #17; 35.x: issue #35) | now (measured) | verdict |" in r.stdout,
          "stdout has the table")
    print(f"{passed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
