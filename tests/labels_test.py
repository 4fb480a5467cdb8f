#!/usr/bin/env python3
"""Every ctest test has a label, and README.md's list of labels names each label in use, so
that `ctest -L unit`, `-L integration` or `-LE slow` select what the README says they do.

    labels_test.py BUILD_DIR README.md
"""
import json
import re
import subprocess
import sys


def main():
    build, readme = sys.argv[1], sys.argv[2]
    listing = subprocess.run(["ctest", "--test-dir", build, "--show-only=json-v1"], check=True,
                             capture_output=True, text=True).stdout
    tests = json.loads(listing)["tests"]
    unlabelled, used = [], set()
    for t in tests:
        labels = next((p["value"] for p in t.get("properties", []) if p["name"] == "LABELS"), [])
        if not labels:
            unlabelled.append(t["name"])
        used.update(labels)
    text = open(readme, encoding="utf-8").read()
    m = re.search(r"^  Labels: (.*?)\.$", text, re.M | re.S)
    listed = set(re.findall(r"`([a-z_]+)`", m.group(1))) if m else set()
    ok = True
    if unlabelled:
        ok = False
        print(f"{len(unlabelled)} of {len(tests)} tests have no label, e.g. {unlabelled[:5]}")
    if not m:
        ok = False
        print(f"{readme}: no line '  Labels: ...' found")
    elif used - listed:
        ok = False
        print(f"{readme}: labels in use but not in its 'Labels:' list: {sorted(used - listed)}")
    elif listed - used:
        ok = False
        print(f"{readme}: its 'Labels:' list names labels no test has: {sorted(listed - used)}")
    print(f"{len(tests)} tests, labels {sorted(used)}: {'ok' if ok else 'FAILED'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
