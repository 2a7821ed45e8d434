"""The routine docs and test edits for a fresh block's lanes: after ``fresh_block_lanes.py --start A --end E --json
PLAN --run`` (in a clean copy; the lane and screen JSONs copied into ``benchmarks/results``), this writes each kept
round's sentence for the block (``Lane u, run with SHA: the 4 of 45600-45799 (...); it acted in none.``), its command
lines and table row in ``docs/readme/diagnose_testbench.md``, the counts of its reading, and extends the round's
table test (its letters, the block's keys or screen sizes, the counts) the way the previous block's edits did.

It writes nothing when anything is off: a rule that acted in a lane, a screen that lists logs where its round
needs a hand-written reading, or a round whose sentence it does not know (rounds 92, 104, 105 with keys; 90, 95 and
108 with keys are written).  A lane where a rule acted takes its hand-written clause from the environment:
``FRESH_LANE_96="on and off: ..."`` (round 96's on/off change, a lost wrong name or a mended log included),
``FRESH_LANE_97="the guard fired in ..."``, ``FRESH_LANE_98="lane v diagnosed it ...: ..., its kept row"`` (the
clause must end with "its kept row", so that the next block finds it) and ``FRESH_LANE_106="the rule fired ..."``;
the readings and test lines those rounds then need are printed (``BY HAND``), as is anything else it stops on, and
are written by hand after it.  The previous sentence of each round is found in that round's ``###`` section by the
previous letter, so the docs must hold the previous block's sentences as this script (or the hand) wrote them.  It
does not rebuild README.md (``python docs/build_readme.py``).

    python benchmarks/fresh_block_lanes.py --start 45600 --end 45800 --json plan.json    # before --run
    python benchmarks/fresh_block_lane_docs.py plan.json 59470c9 45600 45800              # after the JSONs are in
"""
import json
import os
import re
import subprocess
import sys
from pathlib import Path

if len(sys.argv) != 5 or not all(x.isdigit() for x in sys.argv[3:]):
    print("usage: fresh_block_lane_docs.py PLAN.json SHA START END (START, END: the --start/--end of "
          "fresh_block_lanes.py)", file=sys.stderr)
    sys.exit(2)
PLAN, SHA, A, E = json.load(open(sys.argv[1])), sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
RNG = f"{A}-{E - 1}"
RES = Path("benchmarks/results")
sys.path.insert(0, str(Path(__file__).resolve().parent))
import fresh_block_lanes as FL  # noqa: E402

DOC = Path("docs/readme/diagnose_testbench.md")
doc = DOC.read_text()
tests = {}
log = []


def T(name):
    p = Path("tests") / name
    if name not in tests:
        tests[name] = p.read_text()
    return name


def sub1(text, old, new, what=""):
    n = text.count(old)
    if n != 1:
        raise SystemExit(f"{what}: {n} matches of {old[:150]!r}")
    return text.replace(old, new)


def rsub1(text, pat, repl, what=""):
    ms = list(re.finditer(pat, text))
    if len(ms) != 1:
        raise SystemExit(f"{what}: {len(ms)} matches of {pat[:150]!r}")
    m = ms[0]
    r = repl(m) if callable(repl) else m.expand(repl)
    return text[:m.start()] + r + text[m.end():]


def tsub(name, old, new, count=1):
    t = tests[T(name)]
    n = t.count(old)
    if (count is not None and n != count) or n == 0:
        raise SystemExit(f"{name}: {n} matches (want {count}) of {old[:150]!r}")
    tests[name] = t.replace(old, new)


def trsub(name, pat, repl):
    tests[T(name)] = rsub1(tests[T(name)], pat, repl, name)


def cnt(n):
    return "one" if n == 1 else str(n)


def join(keys):
    ks = [str(k) for k in keys]
    return ks[0] if len(ks) == 1 else ", ".join(ks[:-1]) + " and " + ks[-1]


def acted(n):
    return "it did not act" if n == 1 else "it acted in neither" if n == 2 else "it acted in none"


def fmt_int(n):
    return f"{n:,}"


def load(p):
    return json.loads((RES / p).read_text())


def prev_letter(prefix, kind, new):
    ls = FL.letters(prefix, kind)
    assert ls[-1] == new, (prefix, kind, ls[-3:], new)
    return ls[-2]


def against_row(script, files):
    out = subprocess.run([sys.executable, f"benchmarks/{script}", "--against-off-rows", *[str(RES / f) for f in files]],
                         capture_output=True, text=True, check=True).stdout.strip().split("\n")
    return out[-1]


def lanes_literal(letters):
    """a test's ``lanes=`` argument of :func:`conftest.probe_lanes` for these lane letters: a string while every letter
    is one character, else the list form ``[*"ab...z", "za", ...]``"""
    one, more = [x for x in letters if len(x) == 1], [x for x in letters if len(x) > 1]
    if not more:
        return f'lanes="{"".join(one)}"'
    return f'lanes=[*"{"".join(one)}", ' + ", ".join(f'"{x}"' for x in more) + "]"


def lanes_sub(name, letters):
    """extend the test's ``lanes=`` by the last of ``letters``"""
    tsub(name, lanes_literal(letters[:-1]), lanes_literal(letters))


def row_cells(row):
    return [c.strip() for c in row.strip("|").split("|")]


def section_bounds(marker):
    """(start, end) character offsets of the '### ' section of the doc that holds ``marker``"""
    i = doc.index(marker)
    a = doc.rfind("\n### ", 0, i)
    b = doc.find("\n### ", i)
    return (0 if a < 0 else a), (len(doc) if b < 0 else b)


def doc_rsub_in(marker, pat, repl, what):
    global doc
    a, b = section_bounds(marker)
    doc = doc[:a] + rsub1(doc[a:b], pat, repl, what) + doc[b:]


def doc_sub(old, new, what):
    global doc
    doc = sub1(doc, old, new, what)


def doc_rsub(pat, repl, what):
    global doc
    doc = rsub1(doc, pat, repl, what)


def insert_line_after(line_pred, new_lines, what, last=True):
    """insert new_lines after the last (or only) doc line for which line_pred holds"""
    global doc
    lines = doc.split("\n")
    idx = [i for i, l in enumerate(lines) if line_pred(l)]
    if not idx:
        raise SystemExit(f"{what}: no line")
    i = idx[-1]
    lines[i + 1:i + 1] = new_lines
    doc = "\n".join(lines)


def table_row_after(prefix, prev_lane, row, what):
    insert_line_after(lambda l: l.startswith(f"| `{prefix}_lane_{prev_lane}.json` |"), [row], what)


def bump_count(pattern_fmt, old, new, what):
    """pattern_fmt e.g. 'two logs of {}.'"""
    doc_sub(pattern_fmt.format(old), pattern_fmt.format(new), what)


def lane_info(prefix, L):
    d = load(f"{prefix}_lane_{L}.json")
    return d


def lane_row(script, prefix, L):
    """(row, logs examined, rule fired) of lane ``L``'s --against-off-rows row"""
    row = against_row(script, [f"{prefix}_lane_{L}.json"])
    c = row_cells(row)
    return row, int(c[1]), int(c[2])


def check_quiet(script, prefix, L, what, allow_fired=False):
    row = against_row(script, [f"{prefix}_lane_{L}.json"])
    c = row_cells(row)
    # | JSON | logs | fired | named changed | wrong gained | wrong lost | missed | null | oov | outright | mended | broken |
    nums = [c[1], c[2], c[3], c[4], c[5], c[7], c[8], c[9], c[10], c[11]]
    fired = int(c[2])
    if (fired and not allow_fired) or any(int(x) for x in [c[3], c[4], c[5], c[7], c[8], c[9], c[10], c[11]]) \
            or c[6].split(" -> ")[0] != c[6].split(" -> ")[1]:
        raise SystemExit(f"{what}: the rule acted, write by hand: {row}")
    return row, int(c[1]), fired


P = {it["round"]: it for it in PLAN}

def _quiet_lane(r):
    """(pre, script, keys, L, pL, row) of round ``r``'s lane for the block, which must have keys and not have acted."""
    it = P[r]
    pre, script, keys = it["prefix"], it["script"], it["keys"]
    if not keys:
        raise SystemExit(f"{r}: no keys in this block: by hand")
    L = it["lane"]
    pL = prev_letter(pre, "lane", L)
    row, nl, _ = check_quiet(script, pre, L, str(r))
    assert nl == len(keys), (r, nl, keys)
    return pre, script, keys, L, pL, row


def _lane_cmd_and_row(pre, script, pL, L, keys, row, what, cmd=True):
    """the lane's command line after the previous lane's, and its table row after the previous lane's"""
    if cmd:
        insert_line_after(lambda l: f"{pre}_lane_{pL}.json " in l and l.startswith("OPENBLAS"),
                          [f"OPENBLAS_NUM_THREADS=1 python benchmarks/{script} benchmarks/results/{pre}_lane_{L}.json "
                           f"{' '.join(map(str, keys))}"], f"{what} cmd")
    table_row_after(pre, pL, row, f"{what} table")


def _bump(fmt, add, what, test=None, test_fmt=None):
    """the count in the doc's ``fmt`` (one ``{}``, thousands with commas) raised by ``add``, and the same in ``test``
    (its ``test_fmt``, default ``fmt``); the old count"""
    m = re.search(re.escape(fmt).replace(r"\{\}", r"([\d,]+)"), doc)
    if m is None:
        raise SystemExit(f"{what}: no {fmt!r}")
    old = int(m.group(1).replace(",", ""))
    doc_sub(fmt.format(fmt_int(old)), fmt.format(fmt_int(old + add)), what)
    if test:
        tf = test_fmt or fmt
        tsub(test, tf.format(fmt_int(old)), tf.format(fmt_int(old + add)))
    return old



def keys_of(r):
    return P[r]["keys"]


# ---------------------------------------------------------------- round 106
def r106():
    it = P[106]
    pre, script = it["prefix"], it["script"]
    S = it["screens"][0][0]
    pS = prev_letter(pre, "screen", S)
    sc = load(f"{pre}_screen_{S}.json")
    n, gated = len(sc["keys_screened"]), [k for k, _ in sc["touched"]]
    assert sc["refused"] == [], sc["refused"]
    L = it["lane"] if gated else None
    if gated:
        pL = prev_letter(pre, "lane", L)
        # a rule that fired without changing a named effect takes its clause from FRESH_LANE_106 (its reading by hand)
        clause106 = os.environ.get("FRESH_LANE_106")
        row, nl, _ = check_quiet(script, pre, L, "106", allow_fired=bool(clause106))
        assert nl == len(gated)
        word = "one gated" if len(gated) == 1 else f"{len(gated)} gated"
        rule = "the rule did not act" if len(gated) == 1 else ("the rule acted in neither" if len(gated) == 2 else "the rule acted in none")
        rule = clause106 or rule
        new = f" Screen {S} and lane {L}, run with {SHA}: the {n} of {RNG}, {word} ({join(gated)}); {rule}."
    else:
        new = f" Screen {S}, run with {SHA}: the {n} of {RNG}, none gated (no lane)."
    doc_rsub(rf"(Screen {pS}(?: and lane \w+)?, run with \w+: the \d+ of \d+-\d+, [^.]*gated[^.]*\.)", lambda m: m.group(1) + new, "106 prose")
    cmds = [f"python benchmarks/{script} --keys all | tr ' ' '\\n' | awk '$1 >= {A} && $1 < {E}' > k{S}.txt",
            f"OPENBLAS_NUM_THREADS=1 python benchmarks/{script} --screen benchmarks/results/{pre}_screen_{S}.json $(cat k{S}.txt)"]
    if L:
        cmds.append(f"OPENBLAS_NUM_THREADS=1 python benchmarks/{script} benchmarks/results/{pre}_lane_{L}.json $(python benchmarks/{script} --keys screened benchmarks/results/{pre}_screen_{S}.json)")
    insert_line_after(lambda l: f"{pre}_screen_{pS}.json" in l and l.startswith(("OPENBLAS", "python")), cmds, "106 cmds")
    name = "test_diagnose_motion_line_linear_response.py"
    lanes = FL.letters(pre, "lane")
    if L:
        table_row_after(pre, pL, row, "106 table")
        # reading
        m = re.search(r"; (\d+) with ((?:lane \w+'s, )*lane \w+'s) and (lane \w+'s), where it did not act\)\.", doc)
        # after a hand-written clause (a lane where the rule fired), the list goes on with a clause of its own
        m2 = re.search(r"; (?:\w+ of )?(\d+) with lane \w+'s[^;()]*\)\. In 44020", doc)
        if clause106:
            log.append("106: the rule fired: its reading and the test's reading BY HAND")
        elif not m and not m2:
            raise SystemExit("106 reading")
        if not clause106:
            if m:
                old = m.group(0)
                newr = f"; {int(m.group(1)) + len(gated)} with {m.group(2)}, {m.group(3)} and lane {L}'s, where it did not act)."
            else:
                old = m2.group(0)[:-len(". In 44020")]
                newr = old[:-1] + f"; {int(m2.group(1)) + len(gated)} with lane {L}'s, where it did not act)"
            doc_sub(old, newr, "106 reading")
            tsub(name, " ".join(old.split()), " ".join(newr.split()))
        lanes_sub(name, lanes)
        idx = len(lanes) - 1
    else:
        idx = None
    trsub(name, r'(\("\w+", \d+, \d+, \[[\d, ]*\], (?:\d+|None))\)\):\n',
          lambda m: m.group(1) + f"),\n                                     (\"{S}\", {A}, {n}, {gated}, {idx})):\n")
    log.append(f"106 screen {S} ({n}, gated {gated})" + (f" lane {L}" if L else ""))


# ------------------------------------------------ lane rounds of the form "Lane X, run with SHA: the N of R (keys); acted."
LANE_ROUNDS = {
    102: ("test_diagnose_time_law_beside_stribeck_filter_slope.py", "The rule acted in two logs of {}."),
    101: ("test_diagnose_rescue_filter_slope.py", "The rule acted in four logs of {}."),
    100: ("test_diagnose_change_refined_before_position_law.py", "The rule acted in two logs of {}."),
}


def lane_round(r):
    it = P[r]
    pre, script = it["prefix"], it["script"]
    keys = it["keys"]
    name, count_fmt = LANE_ROUNDS[r]
    if not keys:
        # "The fresh blocks A-B have none." after the round's last lane sentence, or that sentence's range extended
        pL = FL.letters(pre, "lane")[-1]
        a, b = section_bounds(f"{pre}_lane_{pL}.json")
        m = re.search(rf"Lane {pL}, run with \w+(?: \([^)]*\))?: the [^;]*; it (?:acted in none|acted in neither|did not act)\."
                      rf"(?: The fresh blocks (\d+)-(\d+) have none\.)?", doc[a:b])
        if m is None:
            raise SystemExit(f"{r}: no keys in this block, and its last lane sentence (lane {pL}) is not found")
        if m.group(2) is not None and int(m.group(2)) == A - 1:
            new_text = m.group(0).replace(f"{m.group(1)}-{m.group(2)} have none", f"{m.group(1)}-{E - 1} have none")
        else:
            new_text = m.group(0) + f" The fresh blocks {RNG} have none."
        doc_rsub_in(f"{pre}_lane_{pL}.json", re.escape(m.group(0)), lambda _: new_text, f"{r} none")
        log.append(f"{r} none")
        return
    L = it["lane"]
    pL = prev_letter(pre, "lane", L)
    row, nl, _ = check_quiet(script, pre, L, str(r))
    d = load(f"{pre}_lane_{L}.json")
    assert d["keys_examined"] == keys and nl == len(keys), (r, d["keys_examined"], keys)
    new = f"Lane {L}, run with {SHA}: the {cnt(len(keys))} of {RNG} ({join(keys)}); {acted(len(keys))}."
    doc_rsub_in(f"{pre}_lane_{pL}.json", rf"(Lane {pL}, run with \w+(?: \([^)]*\))?: the [^;]*; it (?:acted in none|acted in neither|did not act)\.(?: The fresh blocks \d+-\d+ have none\.)?)",
             lambda m: m.group(1) + " " + new, f"{r} prose")
    insert_line_after(lambda l: f"{pre}_lane_{pL}.json " in l and l.startswith("OPENBLAS"),
                      [f"OPENBLAS_NUM_THREADS=1 python benchmarks/{script} benchmarks/results/{pre}_lane_{L}.json {' '.join(map(str, keys))}"],
                      f"{r} cmd")
    table_row_after(pre, pL, row, f"{r} table")
    # count
    a, b = section_bounds(f"{pre}_lane_{pL}.json")
    m = re.search(re.escape(count_fmt).replace(r"\{\}", r"([\d,]+)"), doc[a:b])
    old = int(m.group(1).replace(",", ""))
    doc_rsub_in(f"{pre}_lane_{pL}.json", re.escape(count_fmt.format(fmt_int(old))),
                lambda m: count_fmt.format(fmt_int(old + len(keys))), f"{r} count")
    tsub(name, count_fmt.format(fmt_int(old)), count_fmt.format(fmt_int(old + len(keys))))
    lanes = FL.letters(pre, "lane")
    lanes_sub(name, lanes)
    # keys line: after the last "assert keys[i] == [k for k in touchable if ..."
    t = tests[name]
    ms = list(re.finditer(r"\n(    assert keys\[(\d+)\] == [^\n]*)", t))
    last = max(ms, key=lambda m: int(m.group(2)))
    i = int(last.group(2)) + 1
    assert i == len(lanes) - 1, (r, i, lanes)
    line = f"\n    assert keys[{i}] == [k for k in touchable if {A} <= k < {E}] == {keys}"
    tests[name] = t[:last.end()] + line + t[last.end():]
    log.append(f"{r} lane {L} ({len(keys)})")


# --------------------------------------------------------------- round 99 (screen; lane if listed)
def r99():
    it = P[99]
    pre, script = it["prefix"], it["script"]
    S = it["screens"][0][0]
    pS = prev_letter(pre, "screen", S)
    sc = load(f"{pre}_screen_{S}.json")
    n, listed = len(sc["keys_screened"]), [k for k, _ in sc["touched"]]
    if listed or sc["refused"]:
        raise SystemExit(f"99 listed {listed} refused {sc['refused']}: by hand")
    doc_rsub_in(f"{pre}_screen_{pS}.json", rf"(Screen {pS}, run with \w+: the \d+ of \d+-\d+, none listed \(no lane\)\.)",
             lambda m: m.group(1) + f" Screen {S}, run with {SHA}: the {n} of {RNG}, none listed (no lane).", "99 prose")
    screen_cmds(pre, script, pS, S, f"k{S}.txt", "touchable", [(S, None)])
    name = "test_diagnose_ripple_split_locked.py"
    tsub(name, f'"{pS}")}}', f'"{pS}", "{S}")}}')
    trsub(name, r'(\("\w+", \d+, \d+\))\):\n', lambda m: m.group(1) + f', ("{S}", {n}, {A})):\n')
    # the screens d.. as a string of letters while they are single, then as a list ([*"d..z", "za", ...])
    ls = [x for x in FL.letters(pre, "screen") if x >= "d" or len(x) > 1]
    single = "".join(x for x in ls[:-1] if len(x) == 1)
    multi = [x for x in ls[:-1] if len(x) > 1]
    old_form = f'for x in "{single}"' if not multi else f'for x in [*"{single}", ' + ", ".join(f'"{x}"' for x in multi) + "]"
    single_new = "".join(x for x in ls if len(x) == 1)
    multi_new = [x for x in ls if len(x) > 1]
    new_form = f'for x in "{single_new}"' if not multi_new else f'for x in [*"{single_new}", ' + ", ".join(f'"{x}"' for x in multi_new) + "]"
    tsub(name, old_form, new_form)
    tsub(name, f"# screens d-{pS}:", f"# screens d-{S}:")
    log.append(f"99 screen {S} ({n})")


def screen_cmds(pre, script, pS, S, newfile, keysmode, screens, lane=None, lane_cmd=None):
    """bound the previous screen's awk line, add the new awk + screen (+ lane) lines after the previous block's lines"""
    global doc
    lines = doc.split("\n")
    i_scr = [i for i, l in enumerate(lines) if l.startswith("OPENBLAS") and f"--screen benchmarks/results/{pre}_screen_{pS}.json" in l]
    assert len(i_scr) == 1, (pre, pS)
    j = i_scr[0] - 1
    while not lines[j].startswith("python"):
        j -= 1
    m = re.search(r"awk '\$1 >= (\d+)' > (\S+)", lines[j])
    if m:
        lines[j] = lines[j].replace(m.group(0), f"awk '$1 >= {m.group(1)} && $1 < {A}' > {m.group(2)}")
    else:
        assert f"&& $1 < {A}'" in lines[j], lines[j]
    # after the last line that names the previous screen(s) or lane
    k = max(i for i, l in enumerate(lines) if f"{pre}_screen_{pS}" in l or (pS[:-1] and f"{pre}_screen_{pS[:-1]}[" in l))
    new = [f"python benchmarks/{script} --keys {keysmode} | tr ' ' '\\n' | awk '$1 >= {A}' > {newfile}"]
    for x, share in screens:
        sh = f" --lane={share}" if share else ""
        new.append(f"OPENBLAS_NUM_THREADS=1 python benchmarks/{script} --screen benchmarks/results/{pre}_screen_{x}.json{sh} $(cat {newfile})")
    if lane_cmd:
        new.append(lane_cmd)
    lines[k + 1:k + 1] = new
    doc = "\n".join(lines)


# --------------------------------------------------------------- round 98 (screen; lane on the listed)
def r98():
    it = P[98]
    pre, script = it["prefix"], it["script"]
    S = it["screens"][0][0]
    pS = prev_letter(pre, "screen", S)
    sc = load(f"{pre}_screen_{S}.json")
    n, listed = len(sc["keys_screened"]), [k for k, _ in sc["touched"]]
    assert sc["refused"] == []
    name = "test_diagnose_speed_curve_adc_guarded.py"
    L = None
    if listed:
        L = it["lane"]
        pL = prev_letter(pre, "lane", L)
        # a lane where the rule marked a law takes its clause from FRESH_LANE_98 (ending "its kept row"; reading by hand)
        clause98 = os.environ.get("FRESH_LANE_98")
        if clause98:
            row, nl, fired = lane_row(script, pre, L)
            log.append("98: the rule marked a law: its reading BY HAND")
        else:
            row, nl, fired = check_quiet(script, pre, L, "98")
        assert nl == len(listed)
        if clause98:
            new = f" Screen {S}, run with {SHA}: the {n} of {RNG}, {cnt(len(listed))} listed ({join(listed)}); {clause98}."
        elif len(listed) == 1:
            new = f" Screen {S}, run with {SHA}: the {n} of {RNG}, one listed ({listed[0]}); lane {L} diagnosed it with the rule on, and it marked no law."
        else:
            new = f" Screen {S}, run with {SHA}: the {n} of {RNG}, {len(listed)} listed ({join(listed)}); lane {L} diagnosed them with the rule on, and it marked no law."
        lane_cmd = (f"OPENBLAS_NUM_THREADS=1 python benchmarks/{script} benchmarks/results/{pre}_lane_{L}.json $(python "
                    f"benchmarks/{script} --keys screened benchmarks/results/{pre}_screen_{S}.json)")
    else:
        new = f" Screen {S}, run with {SHA}: the {n} of {RNG}, none listed (no lane)."
        lane_cmd = None
    doc_rsub_in(f"{pre}_screen_{pS}.json", rf"(Screen {pS}, run with \w+: the \d+ of \d+-\d+, (?:none listed \(no lane\)|[^.]*marked no law|[^.]*its kept row)\.)",
             lambda m: m.group(1) + new, "98 prose")
    screen_cmds(pre, script, pS, S, f"k{S}.txt", "touchable", [(S, None)], lane_cmd=lane_cmd)
    if L:
        table_row_after(pre, pL, row, "98 table")
        lanes_sub(name, FL.letters(pre, "lane"))
        trsub(name, r'(\((\d+), "\w+", \[[\d, ]*\]\))\):\n',
              lambda m: m.group(1) + f', ({int(m.group(2)) + 1}, "{S}", {listed})):\n')
    tsub(name, f'"{pS}")}}', f'"{pS}", "{S}")}}')
    tsub(name, f'"{pS}"] for k in screens[x]["keys_screened"])', f'"{pS}", "{S}"] for k in screens[x]["keys_screened"])')
    trsub(name, r"(and len\(loop\) == 7296[ +\d]*)\n", lambda m: m.group(1) + f" + {n}\n")
    trsub(name, r'(\("\w+", \d+, \d+, \[[\d, ]*\]\))\]\n', lambda m: m.group(1) + f', ("{S}", {n}, {A}, {listed})]\n')
    log.append(f"98 screen {S} ({n}, listed {listed})" + (f" lane {L}" if L else ""))


# ------------------------------------------------------ round 96 (two screens, lane on/off) and round 97 (its lane)
def r96_97():
    it = P[96]
    pre, script = it["prefix"], it["script"]
    (S1, _), (S2, _) = it["screens"]
    ls = FL.letters(pre, "screen")
    assert ls[-2:] == [S1, S2], ls[-4:]
    pS1, pS2 = ls[-4], ls[-3]
    scs = [load(f"{pre}_screen_{x}.json") for x in (S1, S2)]
    n = sum(len(s["keys_screened"]) for s in scs)
    listed = sorted(k for s in scs for k, _ in s["touched"])
    assert all(s["refused"] == [] for s in scs)
    name = "test_diagnose_beyond_training_positions.py"
    L = it["lane"] if listed else None
    if L:
        pL = prev_letter(pre, "lane", L)
        # a change between on and off needs its reading by hand: FRESH_LANE_96="on and off: ..." (the clause)
        clause = os.environ.get("FRESH_LANE_96")
        if clause:
            row = against_row(script, [f"{pre}_lane_{L}.json"])
            c = row_cells(row)
            nl, fired = int(c[1]), int(c[2])
            if any(int(x) for x in [c[4], c[7], c[8], c[9], c[11]]):     # a wrong name lost or a mended log: read by the clause
                raise SystemExit(f"96: more than a named effect changed: {row}")
        else:
            row, nl, fired = check_quiet(script, pre, L, "96", allow_fired=True)
            clause = "on and off: nothing changed"
        assert nl == len(listed) and fired == nl, (nl, fired, listed)
        lst = f"one listed ({listed[0]})" if len(listed) == 1 else f"{len(listed)} listed"
        new = f"Screens {S1} and {S2} and lane {L}, run with {SHA}: the {n} of {RNG}, {lst}, {clause}. "
        lane_cmd = (f"OPENBLAS_NUM_THREADS=1 python benchmarks/{script} benchmarks/results/{pre}_lane_{L}.json $(python "
                    f"benchmarks/{script} --keys screened benchmarks/results/{pre}_screen_{S1[:-1]}[{S1[-1]}{S2[-1]}].json)")
        assert S1[:-1] == S2[:-1]
    else:
        raise SystemExit("96: none listed, by hand")
    doc_rsub_in(f"{pre}_screen_{pS2}.json", rf"(Screens {pS1} and {pS2} and lane \w+, run with \w+: the \d+ of \d+-\d+, [^:]*, on and off: [^.]*\. )",
             lambda m: m.group(1) + new, "96 prose")
    screen_cmds(pre, script, pS2, S1, f"k{S1}.txt", "all", [(S1, "0/2"), (S2, "1/2")], lane_cmd=lane_cmd)
    table_row_after(pre, pL, row, "96 table")
    tsub(name, f'"{pS1}", "{pS2}"]     # "z" before "za"', f'"{pS1}", "{pS2}", "{S1}", "{S2}"]     # "z" before "za"')
    tsub(name, f'"{pL}"])\n', f'"{pL}", "{L}"])\n')
    trsub(name, r"the fresh blocks 39200-(\d+), run with the switch off", lambda m: f"the fresh blocks 39200-{E - 1}, run with the switch off")
    trsub(name, r'(\(\("\w+", "\w+"\), \d+, \d+, \[[\d, ]*\]\))\]\n',
          lambda m: m.group(1) + f',\n                   (("{S1}", "{S2}"), {A}, {n}, {listed})]\n')
    trsub(name, r'assert s\["fired"\] == s\["examined"\] == (\d+)\n',
          lambda m: f'assert s["fired"] == s["examined"] == {int(m.group(1)) + len(listed)}\n')
    log.append(f"96 screens {S1},{S2} ({n}, listed {listed}) lane {L}")
    # ---- 97
    it = P[97]
    pre7, script7 = it["prefix"], it["script"]
    L7 = it["lane"]
    pL7 = prev_letter(pre7, "lane", L7)
    # a guard that fired needs its reading by hand: FRESH_LANE_97="the guard fired in ..." (the parenthesis)
    clause7 = os.environ.get("FRESH_LANE_97")
    if clause7:
        row7, nl7, fired7 = lane_row(script7, pre7, L7)
    else:
        row7, nl7, fired7 = check_quiet(script7, pre7, L7, "97")
    assert nl7 == len(listed)
    if clause7:
        new7 = f"Lane {L7}, run with {SHA}: the {cnt(len(listed))} its lane {L} lists in {RNG} ({clause7}). "
    elif len(listed) == 1:
        new7 = f"Lane {L7}, run with {SHA}: the one its lane {L} lists in {RNG}, {listed[0]} (the guard did not fire). "
    else:
        new7 = f"Lane {L7}, run with {SHA}: the {len(listed)} its lane {L} lists in {RNG} (the guard fired in none). "
    doc_rsub_in(f"{pre7}_lane_{pL7}.json", rf"(Lane {pL7}, run with \w+: the \w+ its lane \w+ lists in \d+-\d+[^.]*\. )", lambda m: m.group(1) + new7, "97 prose")
    insert_line_after(lambda l: f"{pre7}_lane_{pL7}.json " in l and l.startswith("OPENBLAS"),
                      [f"OPENBLAS_NUM_THREADS=1 python benchmarks/{script7} benchmarks/results/{pre7}_lane_{L7}.json {' '.join(map(str, listed))}"],
                      "97 cmd")
    # table: row before the against-kept row, which is recomputed
    out = subprocess.run([sys.executable, f"benchmarks/{script7}", "--against-kept",
                          *sorted(str(p) for p in RES.glob(f"{pre7}_lane_*.json"))], capture_output=True, text=True,
                         check=True).stdout.strip().split("\n")
    kept_row = [l for l in out if l.startswith("| `against the kept rows`")][0]
    m = re.search(r"\n(\| `against the kept rows` \|[^\n]*)", doc)
    old_kept = m.group(1)
    doc_sub("\n" + old_kept, "\n" + row7 + "\n" + kept_row, "97 table")
    n7 = tests[T("test_diagnose_beyond_positions_concentrated_gain.py")]
    tsub("test_diagnose_beyond_positions_concentrated_gain.py", f'"_lane_{pL7}.json"]', f'"_lane_{pL7}.json", "_lane_{L7}.json"]')
    trsub("test_diagnose_beyond_positions_concentrated_gain.py", r"len\(examined\) == (\d+)\n",
          lambda m: f"len(examined) == {int(m.group(1)) + len(listed)}\n")
    if clause7:
        # the keys where the guard fired join the test's set and count; its comment and any changed count of the
        # against-kept row stay for the hand (printed below)
        fired_keys = sorted(t["k"] for t in load(f"{pre7}_lane_{L7}.json")["touched"])
        trsub("test_diagnose_beyond_positions_concentrated_gain.py", r"(\{38878, [\d, ]+)\} <= set\(",
              lambda m: m.group(1) + "".join(f", {k}" for k in fired_keys) + "} <= set(")
        trsub("test_diagnose_beyond_positions_concentrated_gain.py", r'assert len\(s\["guard_fired"\]\) == (\d+)',
              lambda m: f'assert len(s["guard_fired"]) == {int(m.group(1)) + len(fired_keys)}')
        log.append(f"97: guard fired in {fired_keys}: its test comment BY HAND")
    old_c, new_c = row_cells(old_kept), row_cells(kept_row)
    if old_c[3:] != new_c[3:] or int(new_c[1]) != int(old_c[1]) + len(listed):
        print("NOTE 97 against-kept changed beyond the count:", old_kept, "->", kept_row)
    log.append(f"97 lane {L7} ({len(listed)})")


# --------------------------------------------------------------- round 93 (screen of candidates)
def r93():
    it = P[93]
    pre, script = it["prefix"], it["script"]
    S = it["screens"][0][0]
    pS = prev_letter(pre, "screen", S)
    sc = load(f"{pre}_screen_{S}.json")
    n, listed = len(sc["keys_screened"]), [k for k, _ in sc["touched"]]
    if sc["refused"]:
        raise SystemExit(f"93 listed {listed}, refused {sc['refused']}: by hand")
    name = "test_diagnose_load_untested_direction.py"
    L = lane_cmd = None
    if listed:
        L = it["lane"]
        pL = prev_letter(pre, "lane", L)
        row, nl, _ = check_quiet(script, pre, L, "93")
        assert nl == len(listed)
        which = f"{cnt(len(listed))} with such a joint ({join(listed)})"
        new = f" Screen {S} and lane {L}, run with {SHA}: the {n} of {RNG}, {which}, not marked."
        lane_cmd = (f"OPENBLAS_NUM_THREADS=1 python benchmarks/{script} benchmarks/results/{pre}_lane_{L}.json "
                    f"{' '.join(map(str, listed))}")
    else:
        new = f" Screen {S}, run with {SHA}: the {n} of {RNG}, none (no lane)."
    doc_rsub_in(f"{pre}_screen_{pS}.json", rf"(Screen {pS}(?: and lane \w+)?, run with \w+: the \d+ of \d+-\d+, (?:none \(no lane\)|\w+ with such a joint \([\d, and]+\), not marked)\.)",
                lambda m: m.group(1) + new, "93 prose")
    lines = doc.split("\n")
    prevfile = re.search(r"\$\(cat (kc\d+)\.txt\)", [l for l in lines if f"{pre}_screen_{pS}.json" in l][0]).group(1)
    newfile = f"kc{int(prevfile[2:]) + 1}.txt"
    screen_cmds(pre, script, pS, S, newfile, "candidates", [(S, None)], lane_cmd=lane_cmd)
    tsub(name, f'"{pS}")}}', f'"{pS}", "{S}")}}')
    tests[T(name)], k = re.subn(rf'"{pS}"\](?!\[)', f'"{pS}", "{S}"]', tests[T(name)])
    assert k >= 4, k
    word = " and ".join(map(str, listed)) if listed else "none"
    trsub(name, r"(, \w+ (?:none|[\d and]+))\n(    assert_fresh_screens)", lambda m: m.group(1) + f", {S} {word}\n" + m.group(2))
    trsub(name, r"(assert_fresh_screens\(zip\(\(screens\[x\] for x in [^)]*\]\), \([\d, ]*)\),",
          lambda m: m.group(1) + f", {n}),")
    trsub(name, r"(\d+)\),\n(\s*)strict=True\)\)", lambda m: f"{m.group(1)}, {A}),\n{m.group(2)}strict=True))")
    trsub(name, rf'(    assert \[k for k, _ in screens\["{pS}"\]\["touched"\]\] == \[[\d, ]*\]\n)',
          lambda m: m.group(1) + f'    assert [k for k, _ in screens["{S}"]["touched"]] == {listed}\n')
    if listed:
        table_row_after(pre, pL, row, "93 table")
        m = re.search(r"It marked a load in three logs of (\d+)\.", doc)
        old = int(m.group(1))
        new_n = old + len(listed)
        doc_sub(f"It marked a load in three logs of {old}.", f"It marked a load in three logs of {new_n}.", "93 count")
        doc_sub(f"In the other {old - 3} no load", f"In the other {new_n - 3} no load", "93 other")
        tsub(name, f"It marked a load in three logs of {old}", f"It marked a load in three logs of {new_n}")
        tsub(name, f"assert len(listed) == {old} and", f"assert len(listed) == {new_n} and")
        lanes_sub(name, FL.letters(pre, "lane"))
        trsub(name, r"(assert \[len\(d\[\"keys_examined\"\]\) for _, d in files\] == \[33, 33,[\d, ]*?)\]\n",
              lambda m: m.group(1) + f", {len(listed)}]\n")
    log.append(f"93 screen {S} ({n}, listed {listed})" + (f" lane {L}" if L else ""))


# --------------------------------------------------------------- round 91 (screen and lane, same letter)
def r91():
    it = P[91]
    pre, script = it["prefix"], it["script"]
    S = it["screens"][0][0]
    pS = prev_letter(pre, "screen", S)
    sc = load(f"{pre}_screen_{S}.json")
    n, listed = len(sc["keys_screened"]), [k for k, _ in sc["touched"]]
    assert sc["refused"] == []
    if not listed:
        raise SystemExit("91: none listed: by hand")
    L = it["lane"]
    assert L == S
    row, nl, _ = check_quiet(script, pre, L, "91")
    assert nl == len(listed)
    doc_rsub_in(f"{pre}_screen_{pS}.json", rf"(Screen {pS} and lane {pS}, run with \w+: the \d+ of \d+-\d+, \d+ with such rows?\.)",
             lambda m: m.group(1) + f" Screen {S} and lane {S}, run with {SHA}: the {n} of {RNG}, {len(listed)} with such rows.", "91 prose")
    lines = doc.split("\n")
    prevfile = re.search(r"\$\(cat (kc\d+)\.txt\)", [l for l in lines if f"--screen benchmarks/results/{pre}_screen_{pS}.json" in l][0]).group(1)
    newfile = f"kc{int(prevfile[2:]) + 1}.txt"
    lane_cmd = (f"OPENBLAS_NUM_THREADS=1 python benchmarks/{script} benchmarks/results/{pre}_lane_{L}.json $(python "
                f"benchmarks/{script} --keys screened benchmarks/results/{pre}_screen_{S}.json)")
    screen_cmds(pre, script, pS, S, newfile, "candidates", [(S, None)], lane_cmd=lane_cmd)
    table_row_after(pre, pS, row, "91 table")
    m = re.search(r"It changed a check's outcome in two logs of ([\d,]+)\.", doc)
    old = int(m.group(1).replace(",", ""))
    bump_count("It changed a check's outcome in two logs of {}.", fmt_int(old), fmt_int(old + len(listed)), "91 count")
    name = "test_diagnose_state_check_speeds.py"
    tsub(name, f"It changed a check's outcome in two logs of {fmt_int(old)}", f"It changed a check's outcome in two logs of {fmt_int(old + len(listed))}")
    tsub(name, f"len(fast) == {old} and", f"len(fast) == {old + len(listed)} and")
    trsub(name, r"(screen \w+: the \d+ of \d+-\d+, \d+)\), the probe every screened",
          lambda m: m.group(1) + f"; screen {S}: the {n} of {RNG}, {len(listed)}), the probe every screened")
    tsub(name, f'"{pS}"]     # "z" before "za"', f'"{pS}", "{S}"]     # "z" before "za"')
    tsub(name, f'"{pS}"])\n', f'"{pS}", "{S}"])\n')
    trsub(name, r"(assert_fresh_screens\(zip\(screens\[3:\], \([\d, ]*)\),", lambda m: m.group(1) + f", {n}),")
    trsub(name, r"(\d+)\)\)\)\n", lambda m: f"{m.group(1)}, {A})))\n")
    trsub(name, r"(assert \[len\(d\[\"keys_examined\"\]\) for _, d in files\] == \[541, 540,[\d,\s]*?)\]\n",
          lambda m: m.group(1) + f", {len(listed)}]\n")
    log.append(f"91 screen/lane {S} ({n}, {len(listed)})")


# ------------------------------------------------------------ round 90 (lane on touchable keys)
def r90():
    it = P[90]
    pre, script = it["prefix"], it["script"]
    keys = it["keys"]
    if not keys:
        # after the last lane's sentence: "The fresh blocks A-B have none." (a range ending just before the block
        # extended)
        pL = FL.letters(pre, "lane")[-1]

        def none(m):
            if m.group(3) is not None and int(m.group(3)) == A - 1:
                return m.group(1) + f" The fresh blocks {m.group(2)}-{E - 1} have none."
            return m.group(0) + f" The fresh blocks {RNG} have none."
        doc_rsub_in(f"{pre}_lane_{pL}.json", rf"(Lane {pL}, run with \w+(?: \([^)]*\))?: [\d, and]+, [^.]*?\((?:it did not act|it acted in neither|it acted in none)\)\.)(?: The fresh blocks (\d+)-(\d+) have none\.)?",
                    none, "90 none")
        log.append("90 none")
        return
    pre, script, keys, L, pL, row = _quiet_lane(90)
    if len(keys) == 1:
        new = f" Lane {L}, run with {SHA}: {keys[0]}, the one of {RNG} (it did not act)."
    else:
        new = f" Lane {L}, run with {SHA}: {join(keys)}, the {len(keys)} of {RNG} ({acted(len(keys))})."
    doc_rsub_in(f"{pre}_lane_{pL}.json", rf"(Lane {pL}, run with \w+(?: \([^)]*\))?: [\d, and]+, [^.]*?\((?:it did not act|it acted in neither|it acted in none)\)\.(?: The fresh blocks \d+-\d+ have none\.)?)",
                lambda m: m.group(1) + new, "90 prose")
    _lane_cmd_and_row(pre, script, pL, L, keys, row, "90")
    name = "test_diagnose_closed_rival.py"
    _bump("It acted in 10 of {} rows.", len(keys), "90 count", name, "It acted in 10 of {} rows")
    tsub(name, f'"{pL}"])', f'"{pL}", "{L}"])') if f'"{pL}"])' in tests[T(name)] else tsub(name, 'wxyz"])', f'wxyz", "{L}"])')
    trsub(name, r"(assert \[len\(d\[\"keys_examined\"\]\) for _, d in files\] == \[56, 150,[\d, ]*?)\]\n",
          lambda m: m.group(1) + f", {len(keys)}]\n")
    log.append(f"90 lane {L} ({keys})")


# ------------------------------------------------------------ round 89
def r89():
    pre, script, keys, L, pL, row = _quiet_lane(89)
    doc_rsub(rf"(, run with \w+ \({pL}: [\d, and]+\))\. Each was diagnosed",
             lambda m: m.group(1) + f", and the {cnt(len(keys))} of the fresh blocks {RNG}, run with {SHA} ({L}: {join(keys)}). Each was diagnosed", "89 prose")
    _lane_cmd_and_row(pre, script, pL, L, keys, row, "89")
    name = "test_diagnose_position_friction_dissipation.py"
    _bump("It fired in one log of {}, the design log 30798", len(keys), "89 count", name, "It fired in one log of {}")
    trsub(name, r"(lane \w+ the \d+ of \d+-\d+); every\n", lambda m: m.group(1) + f", lane {L} the {len(keys)} of {RNG}; every\n")
    tsub(name, f'"{pL}"])\n', f'"{pL}", "{L}"])\n')
    trsub(name, r"(assert \[len\(d\[\"keys_examined\"\]\) for _, d in files\] == \[283, 282,[\d,\s]*?)\]\n",
          lambda m: m.group(1) + f", {len(keys)}]\n")
    log.append(f"89 lane {L} ({keys})")


# ------------------------------------------------------------ round 88
def r88():
    pre, script, keys, L, pL, row = _quiet_lane(88)
    doc_rsub(rf"(, run with \w+ \({pL}\)); no open-loop row is touchable",
             lambda m: m.group(1) + f" and the {cnt(len(keys))} of the fresh blocks {RNG}, run with {SHA} ({L}); no open-loop row is touchable", "88 prose")
    _lane_cmd_and_row(pre, script, pL, L, keys, row, "88")
    name = "test_diagnose_disturbance_stationary.py"
    old = _bump("It fired in one log of {}, the design log 31260", len(keys), "88 count", name, "It fired in one log of {}")
    tsub(name, f'len(examined["loop"]) == {old} and', f'len(examined["loop"]) == {old + len(keys)} and')
    trsub(name, r"(lane \w+ the \d+ of \d+-\d+) \(all run with the rule on\)",
          lambda m: m.group(1) + f", lane {L} the {len(keys)} of {RNG} (all run with the rule on)")
    tsub(name, f'"{pL}"])\n', f'"{pL}", "{L}"])\n')
    trsub(name, r"(assert \[len\(d\[\"keys_examined\"\]\) for _, d in files\] == \[349, 349,[\d,\s]*?)\]\n",
          lambda m: m.group(1) + f", {len(keys)}]\n")
    log.append(f"88 lane {L} ({keys})")


# ------------------------------------------------------------ round 74
def r74():
    pre, script, keys, L, pL, row = _quiet_lane(74)
    rows_word = "row" if len(keys) == 1 else "rows"
    new = f"Lane {L}, run with {SHA}: the {cnt(len(keys))} such {rows_word} of the fresh blocks {RNG} ({join(keys)}). "
    doc_rsub_in(f"{pre}_lane_{pL}.json", rf"(Lane {pL}, run with \w+(?: \([^)]*\))?: the \w+ such rows? [^.]*\([\d, and]+\)\. )", lambda m: m.group(1) + new, "74 prose")
    _lane_cmd_and_row(pre, script, pL, L, keys, row, "74", cmd=False)      # its lanes have no command lines
    name = "test_diagnose_position_law_as_accepted.py"
    old = _bump("The rule fired in 2 of all {} such kept rows", len(keys), "74 count")
    tsub(name, f"every one of the {old} touchable", f"every one of the {old + len(keys)} touchable")
    tsub(name, f"assert len(examined) == {old} and", f"assert len(examined) == {old + len(keys)} and")
    trsub(name, r"assert len\(files\) == (\d+)\n", lambda m: f"assert len(files) == {int(m.group(1)) + 1}\n")
    trsub(name, r"(, \w+: [^\n]*)\n(    assert len\(files\))", lambda m: m.group(1) + f", {L}: {RNG}\n" + m.group(2))
    log.append(f"74 lane {L} ({keys})")


# ------------------------------------------------------------ rounds whose 'have none' range moves
def r103():
    if keys_of(103):
        raise SystemExit("103 has keys: by hand")
    doc_rsub(r"\(the fresh blocks 42800-42999 and 43000-(\d+) have none\)", lambda m: f"(the fresh blocks 42800-42999 and 43000-{E - 1} have none)", "103")
    trsub("test_diagnose_time_law_beside_untestable_stribeck.py", r"# 43000-(\d+)\), 42666", lambda m: f"# 43000-{E - 1}), 42666")


# --------------------------------------------------------------- round 108 (lane of the touchable rows, if any)
def r108():
    """The probe paragraph's last clause: a 'have none' that ends just before the block is extended (else one is added);
    a lane that did not act gets its sentence, command line, table row, count and test line."""
    it = P[108]
    pre, script, keys = it["prefix"], it["script"], it["keys"]
    name = "test_diagnose_change_beside_drift.py"
    tail = r"(the rule did not fire\.|the rule acted in (?:neither|none)\.|have\s+no\s+touchable\s+row\.|have none\.)"
    global doc
    a, b = section_bounds(f"{pre}_lane_a.json")
    sec = doc[a:b]
    probe_par = sec[sec.index("**Probe**"):]
    probe_par = probe_par[:probe_par.index("\n\n")]
    last = list(re.finditer(tail, probe_par))[-1]
    m_none = re.search(r"The fresh blocks (\d+)-(\d+) (have none|have\s+no\s+touchable\s+row)\.$", probe_par[:last.end()])
    t = tests[T(name)]
    if not keys:
        if m_none and int(m_none.group(2)) == A - 1:
            lo = m_none.group(1)
            at = a + sec.index("**Probe**") + m_none.start()     # in the probe paragraph: other rounds have the words
            assert doc[at:at + len(m_none.group(0))] == m_none.group(0)
            doc = doc[:at] + f"The fresh blocks {lo}-{E - 1} {m_none.group(3)}." + doc[at + len(m_none.group(0)):]
            tsub(name, f"assert not [k for k in touchable if {lo} <= k < {A}]",
                 f"assert not [k for k in touchable if {lo} <= k < {E}]")
        else:
            new = probe_par[:last.end()] + f" The fresh blocks {RNG} have none."
            doc_sub(probe_par[:last.end()], new, "108 none")
            ms = list(re.finditer(r"\n(    assert (?:keys\[\d+\] == |not \[k for k in touchable if )[^\n]*)", t))
            tests[name] = t[:ms[-1].end()] + f"\n    assert not [k for k in touchable if {A} <= k < {E}]" + t[ms[-1].end():]
        log.append("108 none")
        return
    L = it["lane"]
    pL = prev_letter(pre, "lane", L)
    row, nl, _ = check_quiet(script, pre, L, "108")
    assert nl == len(keys), (nl, keys)
    if len(keys) == 1:
        sent = (f" Lane {L}, run with {SHA}: {keys[0]}, the one touchable row of the fresh blocks {RNG}; the rule did "
                "not fire.")
    else:
        word = "neither" if len(keys) == 2 else "none"
        sent = (f" Lane {L}, run with {SHA}: the {len(keys)} touchable rows of the fresh blocks {RNG} ({join(keys)}); "
                f"the rule acted in {word}.")
    doc_sub(probe_par[:last.end()], probe_par[:last.end()] + sent, "108 prose")
    _lane_cmd_and_row(pre, script, pL, L, keys, row, "108")
    m = re.search(r"\*\*Reading\.\*\* The rule acted in one log of (\d+)\.", doc[a:])
    old = int(m.group(1))
    doc_sub(f"**Reading.** The rule acted in one log of {old}.", f"**Reading.** The rule acted in one log of {old + len(keys)}.",
            "108 count")
    tsub(name, f"The rule acted in one log of {old}.", f"The rule acted in one log of {old + len(keys)}.")
    lanes_sub(name, FL.letters(pre, "lane"))
    i = len(FL.letters(pre, "lane")) - 1
    if m_none and int(m_none.group(2)) == A - 1:     # the 'have none' just before the block: one range with the lane's
        lo = m_none.group(1)
        tests[name] = tests[name].replace(f"\n    assert not [k for k in touchable if {lo} <= k < {A}]", "")
        line = (f"\n    assert keys[{i}] == [k for k in touchable if {lo} <= k < {E}] == {keys}     # {lo}-{A - 1}: none")
    else:
        line = f"\n    assert keys[{i}] == [k for k in touchable if {A} <= k < {E}] == {keys}"
    ms = list(re.finditer(r"\n(    assert (?:keys\[\d+\] == |not \[k for k in touchable if )[^\n]*)", tests[name]))
    tests[name] = tests[name][:ms[-1].end()] + line + tests[name][ms[-1].end():]
    log.append(f"108 lane {L} ({len(keys)})")


def r95_lane():
    """Round 95's lane that did not act: its clause after the last of the list, command line, table row, count and test
    line."""
    it = P[95]
    pre, script, keys, L = it["prefix"], it["script"], it["keys"], it["lane"]
    pL = prev_letter(pre, "lane", L)
    name = "test_diagnose_ripple_where_law_falls.py"
    row, nl, _ = check_quiet(script, pre, L, "95")
    assert nl == len(keys), (nl, keys)
    if len(keys) == 1:
        what = f"{keys[0]}, the one of {RNG}, run with {SHA} (it did not act)"
    else:
        what = (f"{join(keys)}, the {len(keys)} of {RNG}, run with {SHA} "
                f"(it acted in {'neither' if len(keys) == 2 else 'none'})")
    doc_rsub(r"(; (?:lane \w+, [^;]*?\(it [^);]*\)|the fresh blocks \d+-\d+ have none))\. The ninety-fourth round",
             lambda m: f"{m.group(1)}; lane {L}, {what}. The ninety-fourth round", "95 lane")
    insert_line_after(lambda l: f"{pre}_lane_{pL}.json " in l and l.startswith("OPENBLAS"),
                      [f"OPENBLAS_NUM_THREADS=1 python benchmarks/{script} {' '.join(it['args'])} "
                       f"benchmarks/results/{pre}_lane_{L}.json {' '.join(map(str, keys))}"], "95 cmd")
    table_row_after(pre, pL, row, "95 table")
    _bump("The ninety-fifth round's rule acted in four logs of {}.", len(keys), "95 count")
    lanes_sub(name, FL.letters(pre, "lane"))
    t = tests[T(name)]
    i = max(int(x) for x in re.findall(r"f95\[(\d+)\]\[1\]\[\"keys_examined\"\]", t)) + 1
    ms = list(re.finditer(r"\n    assert (?:f95\[\d+\]\[1\]\[\"keys_examined\"\]|not \[k for k in touchable if )[^\n]*", t))
    line = f"\n    assert f95[{i}][1][\"keys_examined\"] == [k for k in touchable if {A} <= k < {E}] == {keys}"
    tests[name] = t[:ms[-1].end()] + line + t[ms[-1].end():]
    log.append(f"95 lane {L} ({len(keys)})")


def r95():
    if keys_of(95):
        return r95_lane()
    # a 'have none' range that ends just before the block is extended; after a lane, a new one is added
    m = re.search(r"the fresh blocks (\d+)-(\d+) have none\. The ninety-fourth round", doc)
    name = "test_diagnose_ripple_where_law_falls.py"
    if m and int(m.group(2)) == A - 1:
        lo = m.group(1)
        doc_rsub(rf"the fresh blocks {lo}-(\d+) have none\. The ninety-fourth round",
                 lambda m: f"the fresh blocks {lo}-{E - 1} have none. The ninety-fourth round", "95")
        trsub(name, rf"assert not \[k for k in touchable if {lo} <= k < (\d+)\]",
              lambda m: f"assert not [k for k in touchable if {lo} <= k < {E}]")
    else:
        doc_rsub(r"(; lane \w+, [^;]*?\(it [^);]*\))\. The ninety-fourth round",
                 lambda m: f"{m.group(1)}; the fresh blocks {RNG} have none. The ninety-fourth round", "95")
        trsub(name, rf"(    assert f95\[\d+\]\[1\]\[\"keys_examined\"\] == \[k for k in touchable if \d+ <= k < {A}\][^\n]*\n)",
              lambda m: m.group(1) + f"    assert not [k for k in touchable if {A} <= k < {E}]\n")


for r in (105, 104):
    if keys_of(r):
        raise SystemExit(f"round {r} has keys {keys_of(r)}: by hand")
if keys_of(92):
    log.append(f"92 has keys {keys_of(92)}: BY HAND")
r106()
for r in (102, 101, 100):
    lane_round(r)
r99()
r98()
r96_97()
r93()
r91()
r90()
r89()
r88()
r74()
r103()
r95()
r108()
DOC.write_text(doc)
for name, t in tests.items():
    (Path("tests") / name).write_text(t)
print("\n".join(log))
