# What an Nsight Compute source page (run.sh's SCENE_source.csv) says: the stall reasons'
# shares, and per SASS opcode its share of the executed instructions, of the stall samples,
# and the mean number of threads that executed it (of 32).
# usage: python3 tests/bench/cuda_ao/sass_mix.py SCENE_source.csv
import collections
import csv
import sys

rows = list(csv.reader(open(sys.argv[1])))
head = rows[1]
data = [r for r in rows[2:] if len(r) == len(head)]
ix = {c: i for i, c in enumerate(head)}


def num(r, c):
    try:
        return float(r[ix[c]].replace(",", "") or 0)
    except ValueError:
        return 0.0


samples = sum(num(r, "Warp Stall Sampling (All Samples)") for r in data)
executed = sum(num(r, "Instructions Executed") for r in data)
print(f"{executed:.3e} warp instructions executed, {samples:.0f} stall samples")
stalls = [c for c in head if c.startswith("stall_") and "Not Issued" not in c]
shares = collections.Counter({c: sum(num(r, c) for r in data) for c in stalls})
for name, v in shares.most_common(8):
    print(f"{v / samples * 100:5.1f}% {name}")
by_op, by_op_samples, by_op_threads = (collections.Counter() for _ in range(3))
for r in data:
    words = r[ix["Source"]].split()
    if not words:
        continue
    op = (words[1] if words[0].startswith("@") and len(words) > 1 else words[0]).split(".")[0]
    by_op[op] += num(r, "Instructions Executed")
    by_op_samples[op] += num(r, "Warp Stall Sampling (All Samples)")
    by_op_threads[op] += num(r, "Thread Instructions Executed")
print("opcode     executed  samples  threads")
for op, n in by_op.most_common(24):
    print(f"{op:10s} {n / executed * 100:7.1f}% {by_op_samples[op] / samples * 100:7.1f}%"
          f" {by_op_threads[op] / max(n, 1):7.1f}")
