#!/usr/bin/env python3
"""Table 2's averages over all 72 rows at the current default, from the committed runs.

No single run has read all 72 rows from one cache (see README.md), so the rows come from
`cached-so-far/table2.json` (the last whole-table read) with every row that a later one-shape
folder here scored replacing its snapshot row. Averages as `eval::shapes::tables`: over the
rows that pass the quality gate ("trusted"), the means of each method's normalized MSE, the
improvement (S - F) / S of the means, and the rows where FreeForm's MSE is lower.

    python3 results/current-default/averages.py
"""
import json
from pathlib import Path

HERE = Path(__file__).resolve().parent
BOUNDARIES = ["fix_side", "pull_farthest", "pull_boundary"]


def rows():
    table = {}
    for row in json.loads((HERE / "cached-so-far" / "table2.json").read_text())["shapes"]:
        table[(row["name"], row["bc"])] = row
    for path in sorted(HERE.glob("*/table2.json")):
        if path.parent.name == "cached-so-far":
            continue
        for row in json.loads(path.read_text())["shapes"]:
            if row.get("ours_mse") is not None:
                table[(row["name"], row["bc"])] = row
    return table


def main():
    table = rows()
    trusted = [r for r in table.values() if r.get("trusted")]
    for r in table.values():
        if not r.get("trusted"):
            print(f"not trusted: {r['name']} {r['bc']}: {r.get('why_untrusted')}")
    print(f"{len(trusted)} of {len(table)} rows trusted\n")
    print("| shapes | BC | n | FreeForm MSE | Simplicits MSE | improvement | FreeForm lower |")
    print("|---|---|---|---|---|---|---|")
    for collection in ["all", "Thingi10K", "classic"]:
        for bc in BOUNDARIES:
            pairs = [
                (r["ours_mse"], r["simplicits_mse"])
                for r in trusted
                if r["bc"] == bc and collection in ("all", r["collection"])
            ]
            ours = sum(p[0] for p in pairs) / len(pairs)
            theirs = sum(p[1] for p in pairs) / len(pairs)
            wins = sum(p[0] < p[1] for p in pairs)
            print(
                f"| {collection} | {bc} | {len(pairs)} | {ours:.3e} | {theirs:.3e} | "
                f"{100 * (theirs - ours) / theirs:+.1f}% | {wins}/{len(pairs)} |"
            )


if __name__ == "__main__":
    main()
