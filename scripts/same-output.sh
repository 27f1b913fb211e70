#!/usr/bin/env bash
# same-output.sh: a fixed battery of `lightvol` commands whose every output (files, stdout,
# stderr, exit status) is recorded and normalised, so that two builds can be shown to give
# the same results to a user: run the battery with each binary, then compare the folders.
#
#   scripts/same-output.sh BIN OUTDIR [REPO_ROOT]   run the battery with BIN into OUTDIR
#   scripts/same-output.sh --diff DIR_A DIR_B       list every differing file; exit 1 if any
#   scripts/same-output.sh --normalise OUTDIR       re-apply the normalisation (idempotent)
#
# REPO_ROOT (default: $LIGHTVOL_REPO, else the current folder) is where data/scenes/ is read
# from. OUTDIR must not exist or be empty. Needs bash, python3 and coreutils.
#
# OUTDIR holds, for each command NAME of the battery, cmd/NAME.cmd (the command line),
# cmd/NAME.status (exit status), cmd/NAME.stdout and, when it is not empty, cmd/NAME.stderr;
# the files the commands write are under out/, the inputs the script makes under in/, and
# checks.txt says which outputs the documentation promises equal (threads, shards) are.
# The script prints each command's wall time and exit status as it goes (not kept).
# Progress bars are not drawn (standard error is a file, not a terminal).
#
# Normalised (text files only; binary outputs such as EXR, PNG, KTX2, DDS, .lvacc must be
# equal byte for byte), because they change from run to run of the same binary:
#   - JSON values of timing and process-measurement keys: `seconds`, `*_seconds`,
#     `*per_second*`, `thread_scaling`, `peak_*` (peak resident memory), `*_ms`, and every
#     number in an object under such a key (bench's `lookups_per_second`);
#   - in text: "in X s", "X Mrays/s", and the `seconds` column of whitespace, Markdown and
#     HTML tables (compare's summary, `table`, the demo's index.html);
#   - the absolute paths of OUTDIR, of the binary (the job files name it) and of the
#     repository, as <OUTDIR>, <BIN> and <REPO>.
# Nothing else is touched: a value that differs between two runs of one binary is a finding.
# Compare runs made on one machine: `gpu-info`, bench's thread count and the core count
# behind the defaults are the machine's.
set -u -o pipefail
export LC_ALL=C TZ=UTC
unset RAYON_NUM_THREADS

usage() {
    sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//' >&2
    exit 2
}

# The normaliser and the comparer (python3): `normalise OUTDIR [BIN] [REPO]`, `diff A B`.
py() {
    python3 - "$@" <<'PYEOF'
import difflib, os, re, signal, sys
signal.signal(signal.SIGPIPE, signal.SIG_DFL)

TIMING_KEY = re.compile(r'^(seconds|[A-Za-z0-9_]*_seconds|[A-Za-z0-9_]*per_second[A-Za-z0-9_]*|thread_scaling|peak_[A-Za-z0-9_]*|[A-Za-z0-9_]*_ms)$')
JSON_NUM = re.compile(r'"([A-Za-z0-9_]+)"(\s*:\s*)(-?[0-9][0-9.eE+-]*|null)')
IN_SECONDS = re.compile(r'\bin [0-9]+(\.[0-9]+)? s\b')
MRAYS = re.compile(r'[0-9]+(\.[0-9]+)? Mrays/s')
HTML_ROW = re.compile(r'^<tr>.*</tr>$')
HTML_CELL = re.compile(r'<(td|th)>(.*?)</(td|th)>')
MASK = '~'

JSON_OBJ = re.compile(r'"([A-Za-z0-9_]+)"\s*:\s*\{')
NUM_VALUE = re.compile(r'(:\s*)(-?[0-9][0-9.eE+-]*)')

def json_keys(text):
    """Numbers under timing keys, and every number in an object under one (`lookups_per_second`)."""
    def sub(m):
        return m.group(0) if not TIMING_KEY.match(m.group(1)) else '"%s"%s"%s"' % (m.group(1), m.group(2), MASK)
    text = JSON_NUM.sub(sub, text)
    out, pos = [], 0
    for m in JSON_OBJ.finditer(text):
        if m.start() < pos or not TIMING_KEY.match(m.group(1)):
            continue
        depth, end = 0, m.end() - 1
        while end < len(text):
            depth += {'{': 1, '}': -1}.get(text[end], 0)
            if depth == 0:
                break
            end += 1
        out.append(text[pos:m.end()])
        out.append(NUM_VALUE.sub(lambda n: n.group(1) + '"%s"' % MASK, text[m.end():end]))
        pos = end
    out.append(text[pos:])
    return ''.join(out)

def tables(lines):
    """The `seconds` column of whitespace, Markdown and HTML tables: a header row that names
    `seconds`, then the rows under it."""
    out = []
    md_col = html_col = ws_col = None
    ws_width = 0
    for line in lines:
        s = line.strip()
        # Markdown: `| ... | seconds | ... |`, a `| --- |` row, then rows.
        if s.startswith('|') and s.endswith('|'):
            cells = [c.strip() for c in s.strip('|').split('|')]
            if 'seconds' in cells:
                md_col = cells.index('seconds')
            elif md_col is not None and len(cells) > md_col and not set(cells[md_col]) <= set('-: '):
                cells[md_col] = MASK
                line = '| ' + ' | '.join(cells) + ' |'
            out.append(line)
            continue
        md_col = None
        # HTML: `<table><tr><th>..</th>...<th>seconds</th></tr>`, then `<tr>` rows.
        if s.startswith('<table>'):
            texts = [c[1] for c in HTML_CELL.findall(s)]
            html_col = texts.index('seconds') if 'seconds' in texts else None
            out.append(line)
            continue
        if html_col is not None and HTML_ROW.match(s):
            k = [0]
            def sub(m):
                i = k[0]
                k[0] += 1
                return '<%s>%s</%s>' % (m.group(1), MASK, m.group(3)) if i == html_col else m.group(0)
            out.append(HTML_CELL.sub(sub, line))
            continue
        html_col = None
        # Whitespace: a header of words that include `seconds`, then rows of as many words.
        words = line.split()
        if 'seconds' in words and all(re.match(r'^[A-Za-z_]+$', w) for w in words):
            ws_col, ws_width = words.index('seconds'), len(words)
        elif ws_col is not None and len(words) == ws_width:
            t = list(re.finditer(r'\S+', line))[ws_col]
            line = line[:t.start()] + MASK + line[t.end():]
        else:
            ws_col = None
        out.append(line)
    return out

def normalise_text(text, paths):
    for p, tag in paths:
        text = text.replace(p, tag)
    text = json_keys(text)
    text = IN_SECONDS.sub('in %s s' % MASK, text)
    text = MRAYS.sub('%s Mrays/s' % MASK, text)
    ends = text.endswith('\n')
    text = '\n'.join(tables(text.split('\n')[:-1] if ends else text.split('\n')))
    return text + ('\n' if ends else '')

def is_text(b):
    if b'\0' in b:
        return False
    try:
        b.decode('utf-8')
        return True
    except UnicodeDecodeError:
        return False

def normalise(root, bin_path, repo):
    paths = []
    for p, tag in [(os.path.realpath(root), '<OUTDIR>'), (os.path.abspath(root), '<OUTDIR>'),
                   (bin_path and os.path.realpath(bin_path), '<BIN>'), (bin_path and os.path.abspath(bin_path), '<BIN>'),
                   (repo and os.path.realpath(repo), '<REPO>'), (repo and os.path.abspath(repo), '<REPO>')]:
        if p and p != '/' and (p, tag) not in paths:
            paths.append((p, tag))
    paths.sort(key=lambda x: -len(x[0]))
    for d, _, files in os.walk(root):
        for f in files:
            path = os.path.join(d, f)
            if os.path.islink(path):
                continue
            with open(path, 'rb') as fh:
                b = fh.read()
            if not is_text(b):
                continue
            t = normalise_text(b.decode('utf-8'), paths)
            nb = t.encode('utf-8')
            if nb != b:
                with open(path, 'wb') as fh:
                    fh.write(nb)

def listing(root):
    entries = {}
    for d, dirs, files in os.walk(root):
        for x in dirs + files:
            path = os.path.join(d, x)
            rel = os.path.relpath(path, root)
            if os.path.islink(path):
                entries[rel] = ('link', os.readlink(path))
            elif os.path.isdir(path):
                entries[rel] = ('dir', None)
            else:
                entries[rel] = ('file', path)
    return entries

def compare(a, b):
    la, lb = listing(a), listing(b)
    bad = 0
    for rel in sorted(set(la) | set(lb)):
        if rel not in lb:
            print('only in %s: %s' % (a, rel)); bad += 1; continue
        if rel not in la:
            print('only in %s: %s' % (b, rel)); bad += 1; continue
        (ka, va), (kb, vb) = la[rel], lb[rel]
        if ka != kb:
            print('differ (%s vs %s): %s' % (ka, kb, rel)); bad += 1; continue
        if ka == 'link':
            if va != vb:
                print('differ (link target): %s' % rel); bad += 1
            continue
        if ka == 'dir':
            continue
        with open(va, 'rb') as fa, open(vb, 'rb') as fb:
            ba, bb = fa.read(), fb.read()
        if ba == bb:
            continue
        bad += 1
        if is_text(ba) and is_text(bb):
            print('differ: %s' % rel)
            d = list(difflib.unified_diff(ba.decode().splitlines(), bb.decode().splitlines(),
                                          'a/' + rel, 'b/' + rel, n=1, lineterm=''))
            for line in d[:40]:
                print('    ' + line)
            if len(d) > 40:
                print('    ... (%d more diff lines)' % (len(d) - 40))
        else:
            first = next((i for i in range(min(len(ba), len(bb))) if ba[i] != bb[i]), min(len(ba), len(bb)))
            print('differ (binary, %d vs %d bytes, first difference at byte %d): %s' % (len(ba), len(bb), first, rel))
    n = len([1 for v in la.values() if v[0] == 'file'])
    if bad:
        print('%d of %d entries differ' % (bad, len(set(la) | set(lb))))
        return 1
    print('no differences (%d files)' % n)
    return 0

if sys.argv[1] == 'normalise':
    normalise(sys.argv[2], sys.argv[3] if len(sys.argv) > 3 else '', sys.argv[4] if len(sys.argv) > 4 else '')
elif sys.argv[1] == 'diff':
    sys.exit(compare(sys.argv[2], sys.argv[3]))
PYEOF
}

case "${1:-}" in
    --diff)
        [ $# -eq 3 ] || usage
        [ -d "$2" ] && [ -d "$3" ] || { echo "same-output.sh: --diff needs two folders" >&2; exit 2; }
        py diff "$2" "$3"
        exit $?
        ;;
    --normalise)
        [ $# -eq 2 ] && [ -d "$2" ] || usage
        py normalise "$2"
        exit $?
        ;;
    -h | --help | "") usage ;;
esac

[ $# -ge 2 ] && [ $# -le 3 ] || usage
BIN_GIVEN=$1
OUTDIR=$2
REPO=${3:-${LIGHTVOL_REPO:-.}}
[ -x "$BIN_GIVEN" ] && [ -f "$BIN_GIVEN" ] || { echo "same-output.sh: $BIN_GIVEN is not an executable file" >&2; exit 2; }
[ -d "$REPO/data/scenes" ] || { echo "same-output.sh: $REPO/data/scenes not found (give the repository root)" >&2; exit 2; }
if [ -e "$OUTDIR" ] && [ -n "$(ls -A "$OUTDIR")" ]; then
    echo "same-output.sh: $OUTDIR exists and is not empty" >&2
    exit 2
fi
BIN=$(cd "$(dirname "$BIN_GIVEN")" && pwd -P)/$(basename "$BIN_GIVEN")
REPO=$(cd "$REPO" && pwd -P)
mkdir -p "$OUTDIR" && OUTDIR=$(cd "$OUTDIR" && pwd -P)

# The scheduler variables that `--shard auto` and the thread count read are the battery's
# own choice: none from the calling environment.
while IFS='=' read -r var _; do
    case $var in SLURM_* | LIGHTVOL_* | JOB_COMPLETION_INDEX | AWS_BATCH_*) unset "$var" ;; esac
done < <(env)

# `lightvol` on the PATH of the commands is BIN (so that usage lines say `lightvol`).
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"; rm -f "$OUTDIR/scenes"' EXIT
mkdir "$TMP/bin" && ln -s "$BIN" "$TMP/bin/lightvol"
LV=$TMP/bin/lightvol

cd "$OUTDIR" || exit 2
ln -s "$REPO/data/scenes" scenes
mkdir -p cmd in out

declare -A SEEN=()
T_START=$(date +%s%N)

# run NAME [VAR=VALUE ...] -- ARGS...: runs `lightvol ARGS` with the variables set, records
# the command, its exit status, stdout and stderr.
run() {
    local name=$1
    shift
    local -a envs=()
    while [ "$1" != "--" ]; do
        envs+=("$1")
        shift
    done
    shift
    if [ -n "${SEEN[$name]:-}" ]; then
        echo "same-output.sh: duplicate command name $name" >&2
        exit 2
    fi
    SEEN[$name]=1
    local line=lightvol a
    for a in "$@"; do
        if [[ $a =~ ^[A-Za-z0-9_./:=,+@%-]+$ ]]; then line+=" $a"; else line+=" '${a//\'/\'\\\'\'}'"; fi
    done
    { [ ${#envs[@]} -gt 0 ] && printf '%s ' "${envs[@]}"; echo "$line"; } >"cmd/$name.cmd"
    local t0 t1 status
    t0=$(date +%s%N)
    env "${envs[@]}" "$LV" "$@" <"/dev/null" >"cmd/$name.stdout" 2>"cmd/$name.stderr"
    status=$?
    t1=$(date +%s%N)
    echo "$status" >"cmd/$name.status"
    [ -s "cmd/$name.stderr" ] || rm -f "cmd/$name.stderr"
    printf '%6d ms  exit %-3s %s\n' $(((t1 - t0) / 1000000)) "$status" "$name"
}

# ---------------------------------------------------------------------------- inputs
# A small glTF with authored lightmap UVs (TEXCOORD_1), which the vendored scenes lack: a
# floor, a wall sunk below it (texels under the floor see back faces) and a ramp.
python3 - in/planes.gltf <<'PYEOF'
import base64, json, struct, sys
def quad(name, corners):
    return dict(name=name, pos=corners, uv=[(0.0, 0.0), (0.0, 1.0), (1.0, 1.0), (1.0, 0.0)], idx=[(0, 1, 2), (0, 2, 3)])
meshes = [
    quad("floor", [(-2, 0, -2), (-2, 0, 2), (2, 0, 2), (2, 0, -2)]),
    quad("wall", [(-1.5, 1.5, -0.5), (1.5, 1.5, -0.5), (1.5, -0.25, -0.5), (-1.5, -0.25, -0.5)]),
    quad("ramp", [(0.5, 0, 0.5), (0.5, 0, 1.5), (1.5, 0.8, 1.5), (1.5, 0.8, 0.5)]),
]
buf = bytearray(); views = []; accs = []; jm = []; nodes = []
def push(data, target, acc):
    while len(buf) % 4:
        buf.append(0)
    views.append({"buffer": 0, "byteOffset": len(buf), "byteLength": len(data), "target": target})
    buf.extend(data)
    acc["bufferView"] = len(views) - 1
    accs.append(acc)
    return len(accs) - 1
for i, m in enumerate(meshes):
    n = len(m["pos"])
    lo = [min(p[c] for p in m["pos"]) for c in range(3)]
    hi = [max(p[c] for p in m["pos"]) for c in range(3)]
    attrs = {"POSITION": push(b"".join(struct.pack("<3f", *p) for p in m["pos"]), 34962,
                              {"componentType": 5126, "count": n, "type": "VEC3", "min": lo, "max": hi})}
    for s in (0, 1):
        attrs["TEXCOORD_%d" % s] = push(b"".join(struct.pack("<2f", *t) for t in m["uv"]), 34962,
                                        {"componentType": 5126, "count": n, "type": "VEC2"})
    idx = push(b"".join(struct.pack("<3H", *t) for t in m["idx"]), 34963,
               {"componentType": 5123, "count": 3 * len(m["idx"]), "type": "SCALAR"})
    jm.append({"name": m["name"], "primitives": [{"attributes": attrs, "indices": idx, "material": 0}]})
    nodes.append({"mesh": i, "name": m["name"]})
doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": list(range(len(nodes)))}], "nodes": nodes,
       "meshes": jm, "materials": [{"name": "grey", "pbrMetallicRoughness": {"baseColorFactor": [0.7, 0.6, 0.5, 1.0]}}],
       "accessors": accs, "bufferViews": views,
       "buffers": [{"byteLength": len(buf), "uri": "data:application/octet-stream;base64," + base64.b64encode(bytes(buf)).decode()}]}
with open(sys.argv[1], "w") as f:
    f.write(json.dumps(doc, sort_keys=True))
PYEOF

OBJ=scenes/cornell_original/CornellBox-Original.obj
OBJ_MM=scenes/cornell_box/cornell_box.obj
LIVING=scenes/living_room/living_room.glb
ROOM=scenes/occlusion_room/room.glb
BREAKFAST=scenes/breakfast_room/BreakfastRoom.gltf
ZDM2=scenes/zdm2/zdm2.glb
PLANES=in/planes.gltf
SURF_LIGHT=(--sky 0.3,0.4,0.6 --sun 1,0.8,0.3:3)
METHODS=(point prefilter doi doi-paper doi-node point+validity point+apv point+vlm point+ddgi)
mkdir -p out/bake out/shards out/adaptive out/info out/export out/shader out/render out/compare \
    out/surface out/cluster out/inspect out/imse out/proxies

# ------------------------------------------------------------------------- the verbs' help
run version -- --version
run help -- --help
for verb in bench bake bake-surface compare demo lint merge proxies render gpu-info imse info table \
    inspect slurm k8s export shader; do
    run "help-$verb" -- "$verb" --help
done
run help-verb -- help bake
run err-no-verb --
run err-bad-verb -- frobnicate
run err-bad-option -- bake builtin:city --no-such-option

# ---------------------------------------------------------------------------- inspect
for s in builtin:city builtin:interior builtin:maze; do
    run "inspect-${s#builtin:}" -- inspect "$s"
done
run inspect-maze-json -- inspect builtin:maze --json
run inspect-obj -- inspect "$OBJ"
run inspect-obj-json -- inspect "$OBJ" --json
run inspect-obj-mm-zup -- inspect "$OBJ_MM" --up z --scale 0.001
run inspect-living -- inspect "$LIVING"
run inspect-room-json -- inspect "$ROOM" --json
run inspect-breakfast -- inspect "$BREAKFAST"
run inspect-breakfast-json-file -- inspect "$BREAKFAST" --json -o out/inspect/breakfast.json
run inspect-zdm2 -- inspect "$ZDM2"
run inspect-planes -- inspect "$PLANES" --sky 0.3,0.4,0.6 --ground 0.1,0.1,0.1 --sun 1,0.8,0.3:3:1
run err-inspect-missing -- inspect scenes/no-such-scene.glb

# ---------------------------------------------------------------------------- lint
run lint-obj-mm -- lint "$OBJ_MM"
run lint-obj-json -- lint "$OBJ" --json --points-per-cell 2 --dirs 32
run lint-maze -- lint builtin:maze
run lint-living-json -- lint "$LIVING" --json --dirs 32 --min-score 10
run lint-room -- lint "$ROOM" --res 6,4,6 --dirs 16 --threads 1

# ---------------------------------------------------------------------------- bake
# Every method, as JSON, on the built-in interior (a closed room: leaks show).
for m in "${METHODS[@]}"; do
    run "bake-interior-$m" -- bake builtin:interior --res 12,10,7 --samples 8 --method "$m" --json \
        -o "out/bake/interior-$m.exr"
done
# The text report (standard error) of a grid method and of an engine baseline.
run bake-maze-doi-text -- bake builtin:maze --samples 8 -o out/bake/maze-doi.exr
run bake-maze-apv-text -- bake builtin:maze --samples 8 --method point+apv -o out/bake/maze-apv.exr
run bake-maze-doi-quiet -- bake builtin:maze --samples 8 --quiet -o out/bake/maze-doi-quiet.exr
run bake-maze-doi-1thread -- bake builtin:maze --samples 8 --threads 1 -o out/bake/maze-doi-1thread.exr
# Gradients and node fits.
run bake-grad-default -- bake builtin:interior --res 12,10,7 --samples 8 --method doi-paper --gradients \
    --json -o out/bake/interior-doi-paper-grad.exr
run bake-grad-default-text -- bake builtin:maze --samples 8 --method doi --gradients -o out/bake/maze-doi-grad.exr
run bake-grad-central -- bake builtin:interior --res 12,10,7 --samples 8 --method doi --gradients central \
    --json -o out/bake/interior-doi-grad-central.exr
run bake-grad-basis -- bake builtin:interior --res 12,10,7 --samples 8 --method prefilter --gradients basis \
    --json -o out/bake/interior-prefilter-grad-basis.exr
run bake-fit-lsq -- bake builtin:interior --res 12,10,7 --samples 8 --method doi-paper --fit lsq --json \
    -o out/bake/interior-doi-paper-lsq.exr
run bake-fit-lsq-text -- bake builtin:maze --samples 8 --method prefilter --fit lsq:0.5 \
    -o out/bake/maze-prefilter-lsq.exr
# SH orders, lights, paths, seeds, grids.
run bake-order2 -- bake builtin:city --samples 4 --order 2 --json -o out/bake/city-order2.exr
run bake-order4 -- bake builtin:city --samples 4 --order 4 --method point --json -o out/bake/city-order4.exr
run bake-city-lights -- bake builtin:city --samples 4 --sky 0.2,0.3,0.5 --ground 0.1,0.1,0.1 \
    --sun 0.3,0.2,1:5:1 --json -o out/bake/city-lights.exr
run bake-city-nosun -- bake builtin:city --samples 4 --no-sun --light sky+indirect --json -o out/bake/city-nosun.exr
run bake-city-bounces -- bake builtin:city --samples 4 --bounces 1 --json -o out/bake/city-bounces1.exr
run bake-city-rr -- bake builtin:city --samples 4 --bounces 1 --russian-roulette --light indirect --json \
    -o out/bake/city-bounces1-rr.exr
run bake-city-seed -- bake builtin:city --samples 4 --seed 7 --spacing 5 --json -o out/bake/city-seed7.exr
run bake-city-bounds -- bake builtin:city --samples 4 --bounds=-20,-20,0,20,20,10 --res 9,9,4 --json \
    -o out/bake/city-bounds.exr
run bake-keep-acc -- bake builtin:maze --samples 8 --method doi-paper --keep-accumulator \
    -o out/bake/maze-doi-paper-acc.exr
# Scene files: glTF (+Y up) and OBJ.
run bake-living -- bake "$LIVING" --res 8,5,10 --samples 8 --json -o out/bake/living-doi.exr
run bake-room-apv -- bake "$ROOM" --res 8,5,8 --samples 4 --method point+apv --light sky+indirect --json \
    -o out/bake/room-apv.exr
run bake-room-doi-text -- bake "$ROOM" --res 8,5,8 --samples 4 --light sky+indirect -o out/bake/room-doi.exr
run bake-breakfast -- bake "$BREAKFAST" --res 4,4,4 --samples 2 --json -o out/bake/breakfast-doi.exr
run bake-zdm2 -- bake "$ZDM2" --res 8,4,8 --samples 2 --method point+ddgi -o out/bake/zdm2-ddgi.exr
run bake-obj -- bake "$OBJ" --res 6,6,6 --samples 8 --json -o out/bake/obj-doi.exr
run bake-obj-doi-paper -- bake "$OBJ" --res 6,6,6 --samples 8 --method doi-paper --gradients -o out/bake/obj-doi-paper-grad.exr
run bake-obj-mm -- bake "$OBJ_MM" --scale 0.001 --res 5,5,5 --samples 8 --method doi-paper --json \
    -o out/bake/obj-mm-doi-paper.exr
run bake-obj-zup -- bake "$OBJ" --up z --res 5,5,5 --samples 4 --method point+vlm -o out/bake/obj-zup-vlm.exr
# Refusals.
run err-bake-method -- bake builtin:city --method nope -o out/bake/never.exr
run err-bake-samples -- bake builtin:city --samples 0 -o out/bake/never.exr
run err-bake-res -- bake builtin:city --res 1,2,3 -o out/bake/never.exr
run err-bake-grad-basis -- bake builtin:city --method doi --gradients basis -o out/bake/never.exr
run err-bake-fit -- bake builtin:city --method doi --fit lsq -o out/bake/never.exr
run err-bake-fit-grad -- bake builtin:city --method doi-paper --fit lsq --gradients -o out/bake/never.exr
run err-bake-baseline-shard -- bake builtin:city --method point+apv --shard 0/2 -o out/bake/never.exr
run err-bake-stray-adaptive -- bake builtin:city --max-level 1 -o out/bake/never.exr
run err-bake-adaptive-grad -- bake builtin:city --adaptive --gradients -o out/bake/never.exr
run err-bake-missing -- bake scenes/no-such-scene.obj -o out/bake/never.exr
run err-bake-sun -- bake builtin:city --sun 0,0,0:1 -o out/bake/never.exr
run err-bake-memory -- bake builtin:city --res 400,400,400 --max-memory-mib 1 -o out/bake/never.exr

# ---------------------------------------------------------------------------- shards, merge
for k in 0 1 2; do
    run "shard-doi-paper-$k" -- bake builtin:maze --samples 8 --method doi-paper --shard "$k/3" \
        -o "out/shards/maze-doi-paper-$k.exr"
done
run shard-doi-paper-json -- bake builtin:maze --samples 8 --method doi-paper --shard 0/3 --json \
    -o out/shards/maze-doi-paper-0-json.exr
run merge-doi-paper -- merge out/shards/maze-doi-paper-0.lvacc out/shards/maze-doi-paper-1.lvacc \
    out/shards/maze-doi-paper-2.lvacc -o out/shards/maze-doi-paper-merged.exr
run merge-doi-paper-exr-keep -- merge out/shards/maze-doi-paper-2.exr out/shards/maze-doi-paper-0.exr \
    out/shards/maze-doi-paper-1.exr -o out/shards/maze-doi-paper-merged2.exr --keep-accumulator
run merge-of-merged -- merge out/shards/maze-doi-paper-merged2.lvacc -o out/shards/maze-doi-paper-merged3.exr
run merge-partial -- merge out/shards/maze-doi-paper-0.lvacc out/shards/maze-doi-paper-2.lvacc \
    -o out/shards/maze-doi-paper-partial.exr --allow-partial
run err-merge-incomplete -- merge out/shards/maze-doi-paper-0.lvacc out/shards/maze-doi-paper-2.lvacc \
    -o out/shards/never.exr
run err-merge-mismatch -- merge out/shards/maze-doi-paper-0.lvacc out/bake/maze-doi-paper-acc.lvacc \
    -o out/shards/never.exr
run bake-whole-doi-paper -- bake builtin:maze --samples 8 --method doi-paper -o out/shards/maze-doi-paper-whole.exr
for k in 0 1; do
    run "shard-point-$k" -- bake builtin:interior --res 12,10,7 --samples 8 --method point --shard "$k/2" \
        -o "out/shards/interior-point-$k.exr"
done
run merge-point -- merge out/shards/interior-point-1.lvacc out/shards/interior-point-0.lvacc \
    -o out/shards/interior-point-merged.exr
# --shard auto, from each scheduler's variables.
run shard-auto-lightvol LIGHTVOL_SHARD=0/3 -- bake builtin:maze --samples 8 --method doi-paper --shard auto \
    -o out/shards/auto-0.exr
run shard-auto-k8s JOB_COMPLETION_INDEX=1 -- bake builtin:maze --samples 8 --method doi-paper --shard auto \
    --shards 3 -o out/shards/auto-1.exr
run shard-auto-slurm SLURM_ARRAY_TASK_ID=12 SLURM_ARRAY_TASK_MIN=10 SLURM_ARRAY_TASK_MAX=12 \
    SLURM_ARRAY_TASK_COUNT=3 SLURM_CPUS_PER_TASK=1 -- bake builtin:maze --samples 8 --method doi-paper \
    --shard auto -o out/shards/auto-2.exr
run shard-auto-aws AWS_BATCH_JOB_ARRAY_INDEX=1 -- bake builtin:maze --samples 8 --method doi-paper --shard auto \
    --shards 3 --quiet -o out/shards/auto-aws-1.exr
run merge-auto -- merge out/shards/auto-0.lvacc out/shards/auto-1.lvacc out/shards/auto-2.lvacc \
    -o out/shards/auto-merged.exr
run err-shard-auto-none -- bake builtin:maze --samples 8 --shard auto -o out/shards/never.exr

# ---------------------------------------------------------------------------- adaptive
run adaptive-city -- bake builtin:city --adaptive --res 9,9,4 --samples 4 --json -o out/adaptive/city.exr
run adaptive-city-text -- bake builtin:city --adaptive --res 9,9,4 --samples 4 -o out/adaptive/city-text.exr
run adaptive-options -- bake builtin:interior --adaptive --samples 4 --res 7,6,4 --min-level 1 --max-level 2 \
    --gradient-threshold off --depth-ratio 0.5 --depth-rays 8 --cull-tolerance 0.02 --node-budget 2000 \
    --json -o out/adaptive/interior-options.exr
run adaptive-no-geometry -- bake builtin:maze --adaptive --samples 4 --max-level 1 --no-geometry-split \
    --json -o out/adaptive/maze-nogeo.exr
# Level by level in shards, then assembled (what `slurm --adaptive` runs).
A=(bake builtin:city --adaptive --res 9,9,4 --max-level 2 --samples 4)
for k in 0 1; do run "adaptive-shard-l0-$k" -- "${A[@]}" --shard "$k/2" -o "out/adaptive/level0-$k.exr"; done
for k in 0 1; do
    run "adaptive-shard-l1-$k" -- "${A[@]}" --shard "$k/2" --level 1 \
        --from-shards out/adaptive/level0-0.lvacc out/adaptive/level0-1.lvacc -o "out/adaptive/level1-$k.exr"
done
for k in 0 1; do
    run "adaptive-shard-l2-$k" -- "${A[@]}" --shard "$k/2" --level 2 \
        --from-shards out/adaptive/level0-0.lvacc out/adaptive/level0-1.lvacc \
        out/adaptive/level1-0.lvref out/adaptive/level1-1.lvref -o "out/adaptive/level2-$k.exr"
done
run adaptive-assemble -- "${A[@]}" --from-shards out/adaptive/level0-0.lvacc out/adaptive/level0-1.lvacc \
    out/adaptive/level1-0.lvref out/adaptive/level1-1.lvref out/adaptive/level2-0.lvref \
    out/adaptive/level2-1.lvref -o out/adaptive/city-assembled.exr
run adaptive-whole -- "${A[@]}" -o out/adaptive/city-whole.exr
run err-adaptive-incomplete -- "${A[@]}" --from-shards out/adaptive/level0-0.lvacc out/adaptive/level1-0.lvref \
    -o out/adaptive/never.exr
run err-adaptive-level-noshard -- "${A[@]}" --level 1 -o out/adaptive/never.exr

# ---------------------------------------------------------------------------- info
for v in interior-doi interior-point+apv interior-doi-paper-grad interior-doi-paper-lsq city-order2 obj-doi \
    room-apv; do
    run "info-$v" -- info "out/bake/$v.exr"
    run "info-$v-json" -- info "out/bake/$v.exr" --json
done
run info-merged -- info out/shards/maze-doi-paper-merged.exr
run info-shard-json -- info out/shards/maze-doi-paper-1.exr --json
run info-adaptive -- info out/adaptive/city.exr
run info-adaptive-json -- info out/adaptive/interior-options.exr --json
run err-info-missing -- info out/bake/no-such.exr
run err-info-not-volume -- info "$OBJ"

# ---------------------------------------------------------------------------- export
V=out/bake/interior-doi.exr
run export-ktx2 -- export "$V" --format ktx2 -o out/export/interior-doi.ktx2
run export-dds -- export "$V" --format dds -o out/export/interior-doi.dds
run export-bevy -- export "$V" --format bevy -o out/export/interior-doi-bevy.ktx2
run export-bevy-rgb9e5 -- export "$V" --format bevy --bevy-format rgb9e5 -o out/export/interior-doi-bevy-rgb9e5.ktx2
run export-json -- export "$V" --format json -o out/export/interior-doi.json
run export-apv-bevy -- export out/bake/interior-point+apv.exr --format bevy -o out/export/interior-apv-bevy.ktx2
run export-apv-ktx2 -- export out/bake/interior-point+apv.exr --format ktx2 -o out/export/interior-apv.ktx2
run export-grad-dds -- export out/bake/interior-doi-paper-grad.exr --format dds -o out/export/interior-grad.dds
run export-order4-ktx2 -- export out/bake/city-order4.exr --format ktx2 -o out/export/city-order4.ktx2
run export-living-bevy -- export out/bake/living-doi.exr --format bevy -o out/export/living-bevy.ktx2
run export-adaptive-ktx2 -- export out/adaptive/city.exr --format ktx2 -o out/export/adaptive.ktx2
run export-adaptive-ktx2-res -- export out/adaptive/city.exr --format ktx2 --res 9,9,4 -o out/export/adaptive-9.ktx2
run export-adaptive-dds -- export out/adaptive/city.exr --format dds -o out/export/adaptive.dds
run export-adaptive-bevy -- export out/adaptive/city.exr --format bevy --res 17,17,7 -o out/export/adaptive-bevy.ktx2
run export-adaptive-json -- export out/adaptive/city.exr --format json -o out/export/adaptive.json
run err-export-res-uniform -- export "$V" --format ktx2 --res 4,4,4 -o out/export/never.ktx2
run err-export-res-json -- export out/adaptive/city.exr --format json --res 4,4,4 -o out/export/never.json
run err-export-format -- export "$V" --format png -o out/export/never.png

# ---------------------------------------------------------------------------- shader
for lang in wgsl hlsl glsl; do
    for layout in ktx2 native; do
        run "shader-$lang-$layout" -- shader --lang "$lang" --layout "$layout"
    done
done
run shader-default-file -- shader -o out/shader/volume.wgsl

# ---------------------------------------------------------------------------- render
R=(--width 48 --height 32)
run render-volume-png -- render builtin:interior --volume out/bake/interior-doi.exr "${R[@]}" -o out/render/interior-doi.png
run render-volume-exr -- render builtin:interior --volume out/bake/interior-doi.exr "${R[@]}" -o out/render/interior-doi.exr
run render-point-camera -- render builtin:interior --volume out/bake/interior-point.exr "${R[@]}" \
    --camera 5.6,0.4,2.4:2.6,4.6,0.6:80 --exposure 2 -o out/render/interior-point-cam.png
run render-irradiance -- render builtin:interior --volume out/bake/interior-point+apv.exr "${R[@]}" \
    --quantity irradiance -o out/render/interior-apv-irradiance.exr
run render-radiosity -- render builtin:interior --volume out/bake/interior-doi-paper-grad.exr "${R[@]}" \
    --quantity radiosity -o out/render/interior-grad-radiosity.png
run render-adaptive -- render builtin:city --volume out/adaptive/city.exr "${R[@]}" -o out/render/city-adaptive.png
run render-reference-png -- render builtin:interior --reference --reference-samples 4 "${R[@]}" \
    -o out/render/interior-reference.png
run render-reference-exr -- render builtin:interior --reference --reference-samples 4 "${R[@]}" --seed 3 \
    --bounces 1 --light sky+indirect --threads 1 -o out/render/interior-reference.exr
run render-reference-quiet -- render builtin:maze --reference --reference-samples 2 --width 32 --quiet \
    -o out/render/maze-reference.png
run render-living -- render "$LIVING" --volume out/bake/living-doi.exr "${R[@]}" -o out/render/living-doi.png
run render-obj-reference -- render "$OBJ" --reference --reference-samples 4 "${R[@]}" \
    --camera 0,1,3.5:0,1,0:40 -o out/render/obj-reference.png
run render-breakfast-gltf-camera -- render "$BREAKFAST" --reference --reference-samples 2 --width 40 \
    --camera gltf:CameraMain -o out/render/breakfast-main.png
run render-breakfast-gltf-index -- render "$BREAKFAST" --volume out/bake/breakfast-doi.exr --width 40 \
    --camera gltf:2 -o out/render/breakfast-topdown.png
run err-render-novolume -- render builtin:city -o out/render/never.png
run err-render-camera -- render builtin:city --reference --camera 1,2:3 -o out/render/never.png
run err-render-gltf-camera -- render builtin:city --reference --camera gltf:nope -o out/render/never.png
run err-render-size -- render builtin:city --reference --width 0 -o out/render/never.png
# An environment map: the reference EXR above, as a latitude-longitude image.
run bake-env -- bake builtin:city --samples 4 --env out/render/interior-reference.exr --json -o out/bake/city-env.exr

# ---------------------------------------------------------------------------- compare, table
run compare-interior -- compare builtin:interior --res 12,10,7 --samples 8 --plate-res 24 --reference-samples 16 \
    --classify-dirs 32 --methods "$(IFS=,; echo "${METHODS[*]}")" --camera 0.4,0.4,2.4:4,4,1:70 \
    --camera 5.6,0.4,2.4:2.6,4.6,0.6:80 --view-width 32 --view-samples 4 --memory-sweep --sweep-scales 0.5,1 \
    -o out/compare/interior
run compare-maze-lookups -- compare builtin:maze --samples 8 --plate-res 24 --reference-samples 16 \
    --methods doi-paper+taylor,doi-paper+gtrilinear,doi-paper+hermite,doi+hermite,adaptive,adaptive1,doi-paper+lsq,prefilter+average \
    -o out/compare/maze
run compare-city-central -- compare builtin:city --samples 4 --plate-res 20 --reference-samples 8 \
    --methods doi,doi-paper+taylor,point+gtrilinear --gradient-estimator central --fit lsq --plate-height 2 \
    --camera overview --view-width 24 --view-height 16 --view-samples 2 --quiet -o out/compare/city
run compare-obj -- compare "$OBJ" --res 6,6,6 --samples 8 --plate-res 16 --reference-samples 16 \
    --methods point,doi,point+ddgi -o out/compare/obj
run compare-living -- compare "$LIVING" --res 8,5,10 --samples 4 --plate-res 16 --reference-samples 8 \
    --bounces 1 --light sky+indirect --methods point,doi --camera 0,1.5,8:0,1,0:60 --view-width 24 \
    --view-samples 2 -o out/compare/living
run compare-breakfast-gltf-camera -- compare "$BREAKFAST" --res 4,4,4 --samples 2 --plate-res 12 \
    --reference-samples 4 --methods point,doi --camera gltf:CameraTableTop --view-width 24 --view-samples 2 \
    -o out/compare/breakfast
run err-compare-methods -- compare builtin:city --methods "" -o out/compare/never
run err-compare-plate -- compare builtin:city --plate-res 1 -o out/compare/never
run err-compare-scales -- compare builtin:city --memory-sweep --sweep-scales 0 -o out/compare/never
run err-compare-plate-height -- compare builtin:city --plate-height 1000 -o out/compare/never
run table-compare -- table out/compare/interior out/compare/maze out/compare/city out/compare/obj \
    out/compare/living/report.json
run err-table-missing -- table out/compare/never

# ---------------------------------------------------------------------------- demo
run demo-quick -- demo --quick -o out/demo
run table-demo -- table out/demo/city out/demo/interior out/demo/maze out/demo/occlusion_room

# ---------------------------------------------------------------------------- surface maps
run surface-png -- bake-surface "$PLANES" "${SURF_LIGHT[@]}" --basis sh4,hbasis_mod4,hl2 --texels-per-unit 4 \
    --samples 8 --encode png -o out/surface/maps
run surface-json -- bake-surface "$PLANES" "${SURF_LIGHT[@]}" --basis sh9 --texels-per-unit 4 --samples 8 \
    --json -o out/surface/maps-sh9
run surface-compress -- bake-surface "$PLANES" "${SURF_LIGHT[@]}" --basis hbasis_mod6 --texels-per-unit 4 \
    --samples 8 --compress bc1,bc7 --json -o out/surface/maps-bc
run surface-options -- bake-surface "$PLANES" "${SURF_LIGHT[@]}" --basis zernike3,makhotkin4,hsh4 \
    --resolution 16,16 --uv 0 --samples 8 --quantity radiosity --no-invalid-fix --sh-bands 4 --gutter 1 \
    --range 0.5 --encode-scale 0.8 --encode ktx2 --bounces 1 --seed 5 --threads 1 -o out/surface/maps-options
for k in 0 1; do
    run "surface-shard-$k" -- bake-surface "$PLANES" "${SURF_LIGHT[@]}" --basis sh4,hbasis_mod4,hl2 \
        --texels-per-unit 4 --samples 8 --encode png --shard "$k/2" -o out/surface/shards
done
run surface-assemble -- bake-surface "$PLANES" "${SURF_LIGHT[@]}" --basis sh4,hbasis_mod4,hl2 \
    --texels-per-unit 4 --samples 8 --encode png --from-shards out/surface/shards/texels-hl2-1-of-2.lvtex \
    out/surface/shards/texels-sh4-0-of-2.lvtex out/surface/shards/texels-hbasis_mod4-1-of-2.lvtex \
    out/surface/shards/texels-hl2-0-of-2.lvtex out/surface/shards/texels-sh4-1-of-2.lvtex \
    out/surface/shards/texels-hbasis_mod4-0-of-2.lvtex -o out/surface/maps-assembled
run err-surface-incomplete -- bake-surface "$PLANES" "${SURF_LIGHT[@]}" --basis sh4 --texels-per-unit 4 \
    --samples 8 --from-shards out/surface/shards/texels-sh4-0-of-2.lvtex -o out/surface/never
run err-surface-no-uv1 -- bake-surface "$LIVING" --basis sh4 --texels-per-unit 1 --samples 2 -o out/surface/never
run err-surface-basis -- bake-surface "$PLANES" --basis sh5 -o out/surface/never
run render-surface -- render "$PLANES" "${SURF_LIGHT[@]}" --surface out/surface/maps \
    --camera 3,2.5,3:0,0.3,0:50 "${R[@]}" --reference-samples 8 -o out/surface/render
run render-surface-flat -- render "$PLANES" "${SURF_LIGHT[@]}" --surface out/surface/maps-bc \
    --camera 3,2.5,3:0,0.3,0:50 "${R[@]}" --reference-samples 4 --normal-map flat -o out/surface/render-flat
run render-surface-procedural -- render "$PLANES" "${SURF_LIGHT[@]}" --surface out/surface/maps-sh9 \
    --camera 3,2.5,3:0,0.3,0:50 "${R[@]}" --reference-samples 4 --normal-map procedural:4:0.5 \
    -o out/surface/render-procedural
run err-render-surface-lights -- render "$PLANES" --surface out/surface/maps --camera 3,2.5,3:0,0.3,0:50 \
    "${R[@]}" -o out/surface/never
run err-render-surface-reference -- render "$PLANES" --surface out/surface/maps --reference -o out/surface/never

# ---------------------------------------------------------------------------- slurm, k8s (files only)
run slurm -- slurm builtin:maze --method doi-paper --samples 4 --shards 3 -o out/cluster/maze.exr \
    --partition cpu --time 0:10:00 --cpus 2 --mem 1G --lightvol /opt/lightvol/bin/lightvol
run slurm-default-exe -- slurm "$OBJ" --res 6,6,6 --samples 4 --shards 2 --gradients --workdir out/cluster/obj-work \
    -o out/cluster/obj.exr
run slurm-adaptive -- slurm builtin:city --adaptive --max-level 2 --samples 4 --shards 2 \
    -o out/cluster/city-adaptive.exr --lightvol /opt/lightvol/bin/lightvol
run k8s -- k8s builtin:maze --method doi-paper --samples 4 --shards 3 --image registry.invalid/lightvol:1 \
    --workdir out/cluster/k8s --pvc bake-data --mount /mnt/data --cpus 2 -o /mnt/data/maze.exr
run k8s-adaptive -- k8s builtin:city --adaptive --samples 4 --shards 2 --image registry.invalid/lightvol:1 \
    --workdir out/cluster/k8s-adaptive -o /data/city.exr
run err-slurm-shards -- slurm builtin:maze --samples 4 -o out/cluster/never.exr
run err-slurm-baseline -- slurm builtin:maze --method point+apv --shards 2 -o out/cluster/never.exr
run err-slurm-shard -- slurm builtin:maze --shards 2 --shard 0/2 -o out/cluster/never.exr
run err-k8s-image -- k8s builtin:maze --shards 2 -o out/cluster/never.exr

# ---------------------------------------------------------------------------- imse, proxies, bench, gpu-info
run imse -- imse --signals 300
run imse-json -- imse --signals 300 --seed 4 --json
run imse-files -- imse --signals 200 -o out/imse
run proxies -- proxies --size 32 24 --samples 4 --order 3 -o out/proxies/default
run proxies-order4 -- proxies default --size 24 16 --samples 2 -o out/proxies/order4
run proxies-volume -- proxies --volume out/bake/city-lights.exr --size 24 16 --samples 2 -o out/proxies/volume
run proxies-volume-ktx2 -- proxies --volume out/export/interior-doi.ktx2 --size 24 16 --samples 2 \
    -o out/proxies/volume-ktx2
run err-proxies-size -- proxies --size 31 24 -o out/proxies/never
run bench -- bench --rays 2000 --lookups 2000 --samples 2 --scene maze
run gpu-info -- gpu-info
run gpu-info-json -- gpu-info --json

# ---------------------------------------------------------------------------- invariants
# What the documentation promises between the outputs above, recorded in checks.txt.
same() {
    if cmp -s "$1" "$2" || diff -r -q "$1" "$2" >/dev/null 2>&1; then
        echo "same       $1 $2"
    else
        echo "DIFFERENT  $1 $2"
    fi >>checks.txt
}
same out/bake/maze-doi.exr out/bake/maze-doi-1thread.exr
same out/bake/maze-doi.exr out/bake/maze-doi-quiet.exr
same out/shards/maze-doi-paper-merged.exr out/shards/maze-doi-paper-whole.exr
same out/shards/maze-doi-paper-merged2.exr out/shards/maze-doi-paper-whole.exr
same out/shards/maze-doi-paper-merged3.exr out/shards/maze-doi-paper-whole.exr
same out/shards/auto-merged.exr out/shards/maze-doi-paper-whole.exr
same out/shards/interior-point-merged.exr out/bake/interior-point.exr
same out/adaptive/city-assembled.exr out/adaptive/city-whole.exr
same out/adaptive/city.exr out/adaptive/city-text.exr
same out/surface/maps-assembled out/surface/maps

T_END=$(date +%s%N)
rm -f scenes
py normalise "$OUTDIR" "$BIN" "$REPO"
printf 'battery: %d commands in %d s; output in %s\n' "${#SEEN[@]}" $(((T_END - T_START) / 1000000000)) "$OUTDIR"
