#!/usr/bin/env python3
"""Random scenes of their own against the reference: every exact method (hpc, ssv, embree) must
give the reference's bits up to classified ties, and methods the same bytes for 1 and 2 threads,
tiles and shards. exactness_sweep.py varies the examples' lights against Embree; this one builds
the scenes, so it reaches what the examples do not (meshes marked closed that are not watertight,
scenes far from the origin, unusual bake options). CTest runs a few scenes of two modes; a few
seconds per scene, so run more by hand after changing anything the masks depend on:

    python3 tests/tools/scene_sweep.py --mode meshes --seeds 0:100
    python3 tests/tools/scene_sweep.py --mode far --seeds 0:100 --out /tmp/sweep

Modes (docs/reliability.md, "Random scenes against the reference"):
  meshes       OBJ meshes (some marked closed, some not watertight) on a floor, boxes, 1-2 lights
               of every type, max_distance and receiver_offset, a 48x36 camera
  kinds        points (inside meshes too), volume and lightmap receivers; hh and penumbra-map run
  cutouts      grid bars, flowers and grass (cut-outs), boxes, low lights among the blockers,
               cast_shadows/receive_shadows, antialiasing; 1 and 2 threads byte for byte
  far          the cutouts scenes scaled by 1e-3..1e3 and moved up to 1e7 from the origin
  options      the cutouts scenes with random bake options (group size, odd sample counts,
               table bins, leaf size, epsilon, seed, rebuild threshold)
  determinism  the cutouts scenes at 640x480: threads, --memory-budget tiles, shards by
               receivers and by blockers, all the same EXR bytes
Each scene prints one line; a line with "!!!" is a failure. Exit status 1 if any failed.
"""
import argparse, json, math, os, random, re, shutil, subprocess, sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from exactness_sweep import random_light  # noqa: E402
ARGS = None
MESHES = ['cow.obj', 'spot.obj', 'teapot.obj']


def run(args):
    extra = ['-q'] if args[0] in ('bake', 'merge') else []
    return subprocess.run([ARGS.binary] + args + ['--allow-outside-uris'] + extra, capture_output=True, text=True)


def bbox(path):
    lo, hi = [1e30] * 3, [-1e30] * 3
    for line in open(path):
        if line.startswith('v '):
            v = [float(x) for x in line.split()[1:4]]
            lo, hi = [min(a, b) for a, b in zip(lo, v)], [max(a, b) for a, b in zip(hi, v)]
    return lo, hi


def light(rng):
    """exactness_sweep's random light, a rect turned to emit downward (on the side of u x v)."""
    L = random_light(rng)
    if L["type"] == "rect" and L["u"][2] * L["v"][0] - L["u"][0] * L["v"][2] > 0:
        L["v"] = [-x for x in L["v"]]
    return L


def mesh_entry(rng, names, boxes):
    m = rng.choice(names)
    lo, hi = boxes[m]
    sc = rng.uniform(0.8, 2.0) / max(h - l for h, l in zip(hi, lo))
    return {'type': 'obj', 'path': os.path.join(ARGS.data, 'meshes', m), 'closed': rng.random() < 0.4,
            'transform': {'scale': sc, 'rotate_deg': [0, rng.uniform(0, 360), 0],
                          'translate': [rng.uniform(-1.5, 1.5), -lo[1] * sc + rng.choice([0, 0.3]), rng.uniform(-1.5, 1.5)]}}


def random_boxes(rng, n=5):
    return {'type': 'boxes', 'boxes': [[[x, rng.uniform(0, .5), z], [x + rng.uniform(.1, .8), rng.uniform(.6, 1.5), z + rng.uniform(.1, .8)]]
                                       for x, z in [(rng.uniform(-3, 2), rng.uniform(-3, 2)) for _ in range(n)]]}


def camera(rng, w, h):
    return {'type': 'camera', 'eye': [rng.uniform(-4, 4), rng.uniform(2, 6), rng.uniform(3, 7)], 'target': [0, 0.3, 0],
            'up': [0, 1, 0], 'fov_deg': 50, 'width': w, 'height': h}


def meshes_scene(rng, d, boxes):
    geo = [{'type': 'grid', 'levels': 0, 'floor_size': 8}] + [mesh_entry(rng, MESHES, boxes) for _ in range(rng.choice([1, 2]))]
    for g in geo[1:]:
        if rng.random() < 0.2: g['max_distance'] = rng.uniform(0.5, 3)
        if rng.random() < 0.2: g['receiver_offset'] = rng.uniform(-0.01, 0.02)
    if rng.random() < 0.4: geo.append(random_boxes(rng))
    return {'geometry': geo, 'lights': [light(rng) for _ in range(rng.choice([1, 1, 2]))], 'receivers': camera(rng, 48, 36),
            'output': f'{d}/x.exr'}, 'exr'


def kinds_scene(rng, d, boxes):
    import numpy as np
    geo = [{'type': 'grid', 'levels': 0, 'floor_size': 8}] + [mesh_entry(rng, ['cow.obj', 'spot.obj'], boxes) for _ in range(rng.choice([1, 2]))]
    kind = rng.choice(['points', 'volume', 'lightmap'])
    if kind == 'points':
        p = np.zeros((600, 6), np.float32)
        for i in range(600):
            p[i, :3] = [rng.uniform(-2, 2), rng.choice([0.0, rng.uniform(0, 1.5)]), rng.uniform(-2, 2)]
            p[i, 4] = 1 if rng.random() < 0.5 else 0
        np.save(f'{d}/pts.npy', p)
        rec, ext = {'type': 'points', 'path': f'{d}/pts.npy'}, 'npy'
    elif kind == 'volume':
        rec, ext = {'type': 'volume', 'voxel_size': 0.25, 'box': [[-2, 0, -2], [2, 1.5, 2]]}, 'vdb'
    else:
        rec, ext = {'type': 'lightmap', 'meshes': [1], 'resolution': 96, 'padding': 1}, 'exr'
    return {'geometry': geo, 'lights': [light(rng) for _ in range(rng.choice([1, 2]))], 'receivers': rec, 'output': f'{d}/x.{ext}'}, ext


def cutouts_scene(rng, d, boxes=None):
    geo = [{'type': 'grid', 'levels': rng.choice([0, 1, 2]), 'floor_size': 6, 'size': rng.uniform(1, 3), 'cells': rng.choice([3, 5, 8]),
            'height': rng.uniform(0.3, 1.5), 'thickness': rng.choice([0, 0.05, 0.2]), 'bar': rng.uniform(0.05, 0.3)}]
    if rng.random() < 0.6: geo.append({'type': 'flowers', 'count': rng.choice([30, 200]), 'area': [[-2, -2], [2, 2]], 'seed': rng.randrange(1000)})
    if rng.random() < 0.5:
        geo.append({'type': 'grass', 'count': 300, 'area': [[-2, -2], [2, 2]], 'seed': rng.randrange(1000), 'alpha_matte': rng.random() < 0.5})
    if rng.random() < 0.6: geo.append(random_boxes(rng, 4))
    for g in geo[1:]:
        if rng.random() < 0.15: g['cast_shadows'] = False
        if rng.random() < 0.15: g['receive_shadows'] = False
    lights = []
    for _ in range(rng.choice([1, 2])):
        L = light(rng)
        if 'center' in L and rng.random() < 0.5: L['center'][1] = rng.uniform(0.3, 1.6)  # among the blockers
        lights.append(L)
    cam = camera(rng, 40, 30)
    if rng.random() < 0.3: cam['antialias'] = {'threshold': 0.1, 'samples': 4}
    return {'geometry': geo, 'lights': lights, 'receivers': cam, 'output': f'{d}/x.exr'}, 'exr'


def far_scene(rng, d, boxes=None):
    sc, ext = cutouts_scene(rng, d)
    s = rng.choice([1e-3, 0.05, 20.0, 1e3])
    T = rng.choice([[0, 0, 0], [1e4 * s, 0, -3e3 * s], [-50.0, 7.0, 1e3]])
    f = lambda p: [p[i] * s + T[i] for i in range(3)]
    for g in sc['geometry']: g['transform'] = {'scale': s, 'translate': T}
    for L in sc['lights']:
        if 'center' in L: L['center'] = f(L['center'])
        for k in ['u', 'v']:
            if k in L: L[k] = [x * s for x in L[k]]
        if 'radius' in L: L['radius'] *= s
        if 'vertices' in L: L['vertices'] = [f(v) for v in L['vertices']]
    c = sc['receivers']
    c['eye'], c['target'] = f(c['eye']), f(c['target'])
    c.pop('antialias', None)  # each method refines where its own V changes: ties would change the receivers
    return sc, ext


def options_scene(rng, d, boxes=None):
    sc, ext = cutouts_scene(rng, d)
    for L in sc['lights']: L['samples'], L['sample_sets'] = rng.choice([1, 3, 17, 63, 65, 130, 257]), rng.choice([1, 3, 8, 13])
    sc['bake'] = {'group_size': rng.choice([1, 7, 32, 64]), 'sample_table_angles': rng.choice([4, 64, 256]),
                  'sample_table_offsets': rng.choice([1, 16, 128]), 'leaf_size': rng.choice([1, 4, 16, 64]),
                  'median_split_above': rng.choice([2, 64, 1024]), 'epsilon': rng.choice([0, 1e-7, 1e-5, 1e-3]),
                  'seed': rng.randrange(1 << 40), 'rebuild_threshold': rng.choice([0.01, 0.25, 1.0])}
    return sc, ext


def compare(d, scene, m):
    out = run(['compare', f'{d}/reference', f'{d}/{m}', '--scene', scene])
    text = out.stdout + out.stderr
    kv = dict(line.split(' ', 1) for line in text.strip().splitlines() if ' ' in line)
    verdict = '%s/%s t%s' % (kv.get('only_a'), kv.get('only_b'), kv.get('ties'))
    return verdict if kv.get('unexplained') == '0' else verdict + ' !!! ' + text.strip()[-300:]


def against_reference(d, scene, ext, methods=('hpc', 'ssv', 'embree')):
    res = {}
    r = run(['bake', scene, '--method', 'reference', '--dump', f'{d}/reference', '-o', f'{d}/reference.{ext}'])
    if r.returncode: return {'reference': '!!! ' + r.stderr.strip()[-200:]}
    for m in methods:
        r = run(['bake', scene, '--method', m, '--dump', f'{d}/{m}', '-o', f'{d}/{m}.{ext}', '--threads', '2'])
        res[m] = compare(d, scene, m) if r.returncode == 0 else '!!! ' + r.stderr.strip()[-200:]
    return res


def same_bytes(a, b):
    return 'same' if open(a, 'rb').read() == open(b, 'rb').read() else 'DIFFERENT !!!'


def threads(d, scene, ext, methods):
    """Each method on 1 and 2 threads into folders of their own, so that files naming each other
    (a lightmap's glTF names its atlas) are named alike: every file the same bytes."""
    res = {}
    for m in methods:
        for t in (1, 2): os.makedirs(f'{d}/{m}-threads{t}', exist_ok=True)  # -o's folder must exist
        runs = {t: run(['bake', scene, '--method', m, '-o', f'{d}/{m}-threads{t}/out.{ext}', '--threads', str(t)]) for t in (1, 2)}
        if any(r.returncode for r in runs.values()):
            refused = 'applies to' in runs[1].stderr or 'refuse' in runs[1].stderr
            res[m + '-threads'] = 'refused' if refused else '!!! ' + (runs[1].stderr + runs[2].stderr).strip()[-200:]
        else:
            res[m + '-threads'] = same_folders(f'{d}/{m}-threads1', f'{d}/{m}-threads2')
    return res


def same_folders(a, b):
    names = sorted(os.listdir(a))
    if names != sorted(os.listdir(b)): return 'DIFFERENT (files) !!!'
    for f in names:
        if open(os.path.join(a, f), 'rb').read() != open(os.path.join(b, f), 'rb').read(): return f'DIFFERENT ({f}) !!!'
    return 'same'


def determinism(d, scene):
    res = {}
    base = run(['bake', scene, '-o', f'{d}/base.exr', '--threads', '2'])
    if base.returncode: return {'base': '!!! ' + base.stderr.strip()[-200:]}
    r = run(['bake', scene, '-o', f'{d}/t1.exr', '--threads', '1'])
    res['threads'] = same_bytes(f'{d}/base.exr', f'{d}/t1.exr') if not r.returncode else '!!!'
    budget = '1M'
    for _ in range(3):  # the smallest budget the bake accepts (the antialiasing pass may ask again)
        r = run(['bake', scene, '-o', f'{d}/budget.exr', '--memory-budget', budget, '--stats', f'{d}/b.json'])
        m = re.search(r'at least (\d+)M', r.stderr)
        if r.returncode == 0 or not m: break
        budget = m.group(1) + 'M'
    res['tiles'] = json.load(open(f'{d}/b.json'))['memory_plan']['tiles'] if not r.returncode else 0
    res['budget'] = same_bytes(f'{d}/base.exr', f'{d}/budget.exr') if not r.returncode else '!!! ' + r.stderr.strip()[-150:]
    for by in ['receivers', 'blockers']:
        sd = f'{d}/shards-{by}'
        shutil.rmtree(sd, ignore_errors=True)
        failed = next((r for i in range(3) if (r := run(['bake', scene, '--shard', f'{i}/3', '--shard-by', by, '--shard-dir', sd,
                                                           '--threads', '1'])).returncode), None)
        if failed is None:
            r = run(['merge', scene, '--shard-dir', sd, '-o', f'{d}/merge-{by}.exr'])
            res[by] = same_bytes(f'{d}/base.exr', f'{d}/merge-{by}.exr') if not r.returncode else '!!! ' + r.stderr.strip()[-150:]
        else:
            res[by] = '!!! ' + failed.stderr.strip()[-150:]
    return res


def main():
    global ARGS
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--mode', required=True, choices=['meshes', 'kinds', 'cutouts', 'far', 'options', 'determinism'])
    p.add_argument('--seeds', default='0:20', help='first:end (end excluded)')
    p.add_argument('--binary', default=os.path.join(HERE, '..', '..', 'build', 'penumbra'))
    p.add_argument('--data', default=os.path.join(HERE, '..', '..', '..', 'shared', 'data'), help='the shared data folder (meshes/)')
    p.add_argument('--out', default='/tmp/penumbra-sweep')
    ARGS = p.parse_args()
    first, end = (int(x) for x in ARGS.seeds.split(':'))
    boxes = {m: bbox(os.path.join(ARGS.data, 'meshes', m)) for m in MESHES} if ARGS.mode in ('meshes', 'kinds') else None
    make = {'meshes': meshes_scene, 'kinds': kinds_scene, 'cutouts': cutouts_scene, 'far': far_scene, 'options': options_scene,
            'determinism': cutouts_scene}[ARGS.mode]
    failures = 0
    for seed in range(first, end):
        rng = random.Random(f'{ARGS.mode}-{seed}')
        d = os.path.join(ARGS.out, f'{ARGS.mode}-{seed}')
        shutil.rmtree(d, ignore_errors=True)
        os.makedirs(d)
        sc, ext = make(rng, d, boxes)
        if ARGS.mode == 'determinism': sc['receivers']['width'], sc['receivers']['height'] = 640, 480
        scene = os.path.join(d, 'scene.json')
        json.dump(sc, open(scene, 'w'))
        if ARGS.mode == 'determinism':
            res = determinism(d, scene)
        else:
            res = against_reference(d, scene, ext)
            if ARGS.mode in ('kinds', 'cutouts'):
                res.update(threads(d, scene, ext, ['hpc', 'ssv', 'penumbra-map'] + (['hh'] if sc['receivers']['type'] == 'lightmap' else [])))
        line = f'{seed} {json.dumps(res)}'
        failures += '!!!' in line
        print(line, flush=True)
    print(f'{end - first} scenes, {failures} failed', flush=True)
    return 1 if failures else 0


if __name__ == '__main__':
    sys.exit(main())
