"""Compare development runs of one S_MAX against the baselines: per set mean gain, worst, images changed."""
import csv, sys, os
def load(p):
    d = {}
    for r in csv.DictReader(open(p)):
        d[(r['image'], r['method'])] = float(r['psnr_linear'])
    return d
base = {**{f'v{v}': f'/work/scratch/stress/out-v{v}' for v in range(1, 7)},
        'train': '/work/main/tools/results/real-data/hot-pixel/dev-2b/train',
        'ind11': '/work/main/tools/results/real-data/hot-pixel/dev-2b/ind11',
        'night32': '/work/main/tools/results/real-data/hot-pixel/dev-2b/night32'}
S = sys.argv[1]
for name, bdir in base.items():
    p = f'/work/scratch/res/s{S}/{name}/metrics.csv'
    if not os.path.exists(p): print(name, 'not yet'); continue
    b, a = load(bdir + '/metrics.csv'), load(p)
    ims = sorted({k[0] for k in a if k[1] == 'hdrcam'})
    if name == 'night32': ims = ims[16:]
    gb = [b[(i, 'hdrcam')] - b[(i, 'ldr')] for i in ims]; ga = [a[(i, 'hdrcam')] - a[(i, 'ldr')] for i in ims]
    changed = [(i, x, y) for i, x, y in zip(ims, gb, ga) if abs(x - y) > 0.005]
    print(f'{name}: n {len(ims)} mean {sum(gb)/len(ims):+.3f} -> {sum(ga)/len(ims):+.3f}; worst {min(gb):+.3f} -> {min(ga):+.3f}; changed {len(changed)}')
    for i, x, y in changed: print(f'    {i}: {x:+.3f} -> {y:+.3f}')
