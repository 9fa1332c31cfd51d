# The sizeable Function-storage variables of entry points in our SPIR-V, with their types:
# what a driver may keep in local memory, e.g. which traversal stacks a kernel holds (the
# docs/PERFORMANCE.md, "The walk's state in local memory"; compare `kernel_stats`' local memory).
# usage: python3 tests/bench/spirv_vars.py target/spirv-builder/.../kernels.spv \
#          entry::ao_plain_main entry::nee_diffuse_main
import struct
import sys

OP_NAME, OP_ENTRY_POINT, OP_TYPE_BOOL, OP_TYPE_INT, OP_TYPE_FLOAT = 5, 15, 20, 21, 22
OP_TYPE_VECTOR, OP_TYPE_ARRAY, OP_TYPE_STRUCT, OP_TYPE_POINTER = 23, 28, 30, 32
OP_CONSTANT, OP_FUNCTION, OP_VARIABLE, OP_FUNCTION_CALL = 43, 54, 59, 57
STORAGE_FUNCTION = 7
MIN_BYTES = 32

data = open(sys.argv[1], "rb").read()
words = struct.unpack(f"<{len(data) // 4}I", data)


def string(operands):
    """A literal string operand."""
    raw = b"".join(struct.pack("<I", x) for x in operands)
    return raw.split(b"\0")[0].decode()


types, constants, names, entries, variables = {}, {}, {}, {}, {}
function = None
i = 5  # after the header
while i < len(words):
    op, count = words[i] & 0xFFFF, words[i] >> 16
    a = words[i + 1 : i + count]
    if op == OP_ENTRY_POINT:
        entries[string(a[2:])] = a[1]
    elif op == OP_NAME:
        names[a[0]] = string(a[1:])
    elif op in (OP_TYPE_INT, OP_TYPE_FLOAT):
        types[a[0]] = ("scalar", a[1] // 8)
    elif op == OP_TYPE_BOOL:
        types[a[0]] = ("scalar", 4)
    elif op == OP_TYPE_VECTOR:
        types[a[0]] = ("vector", a[1], a[2])
    elif op == OP_TYPE_ARRAY:
        types[a[0]] = ("array", a[1], a[2])
    elif op == OP_TYPE_STRUCT:
        types[a[0]] = ("struct",) + tuple(a[1:])
    elif op == OP_TYPE_POINTER:
        types[a[0]] = ("pointer", a[1], a[2])
    elif op == OP_CONSTANT:
        constants[a[1]] = a[2]
    elif op == OP_FUNCTION:
        function = a[1]
        variables[function] = []
    elif op == OP_VARIABLE and function is not None and a[2] == STORAGE_FUNCTION:
        variables[function].append(("variable", a[0], a[1]))
    elif op == OP_FUNCTION_CALL and function is not None:
        variables[function].append(("call", a[2], None))
    i += count


def size(t):
    d = types[t]
    if d[0] == "scalar":
        return d[1]
    if d[0] == "vector":
        return size(d[1]) * d[2]
    if d[0] == "array":
        return size(d[1]) * constants[d[2]]
    if d[0] == "struct":
        return sum(size(m) for m in d[1:])
    return 0


def describe(t):
    d = types[t]
    if d[0] == "array":
        return f"[{describe(d[1])}; {constants[d[2]]}]"
    if d[0] == "vector":
        return f"{size(d[1]) * 8}-bit x{d[2]}"
    if d[0] == "struct":
        return names.get(t, "struct") + "{" + ", ".join(describe(m) for m in d[1:]) + "}"
    return f"{d[1] * 8}-bit"


for entry in sys.argv[2:]:
    if entry not in entries:
        sys.exit(f"error: no entry point {entry!r}; the module has: {', '.join(sorted(entries))}")
    print(f"== {entry}")
    seen, todo, total = set(), [entries[entry]], 0
    while todo:  # the entry point and every function it calls
        f = todo.pop()
        if f in seen:
            continue
        seen.add(f)
        for kind, target, result in variables.get(f, []):
            if kind == "call":
                todo.append(target)
                continue
            pointee = types[target][2]
            bytes_ = size(pointee)
            if bytes_ >= MIN_BYTES:
                total += bytes_
                print(f"  %{result}: {bytes_} B {describe(pointee)[:200]}")
    print(f"  {total} B in variables of {MIN_BYTES} B and more")
