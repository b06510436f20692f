"""Per-image comparison of two evaluate metrics.csv files (method hdrcam vs ldr): gain and PU21 before/after."""
import csv, sys
def load(p, only=None):
    rows = {}
    for r in csv.DictReader(open(p)):
        rows[(r['image'], r['method'])] = r
    return rows
before, after = load(sys.argv[1]), load(sys.argv[2])
first = int(sys.argv[3]) if len(sys.argv) > 3 else 0
images = sorted({i for i, m in after if m == 'hdrcam'})[first:]
tot = [0, 0, 0, 0]
print('image | gain before | gain after | PU21 before | PU21 after | dPU21')
worst_dpu, newly = 0, []
for im in images:
    l = float(after[(im, 'ldr')]['psnr_linear']); lb = float(before[(im, 'ldr')]['psnr_linear'])
    gb = float(before[(im, 'hdrcam')]['psnr_linear']) - lb; ga = float(after[(im, 'hdrcam')]['psnr_linear']) - l
    pb = float(before[(im, 'hdrcam')]['pu21_psnr']); pa = float(after[(im, 'hdrcam')]['pu21_psnr'])
    tot[0] += gb; tot[1] += ga; tot[2] += pb; tot[3] += pa
    worst_dpu = min(worst_dpu, pa - pb)
    if ga < -0.3 <= gb: newly.append(im)
    if abs(ga - gb) > 0.005 or abs(pa - pb) > 0.005:
        print(f'{im} | {gb:+.3f} | {ga:+.3f} | {pb:.3f} | {pa:.3f} | {pa - pb:+.3f}')
n = len(images)
print(f'mean over {n}: gain {tot[0]/n:+.3f} -> {tot[1]/n:+.3f}; PU21 {tot[2]/n:.3f} -> {tot[3]/n:.3f}; worst dPU21 {worst_dpu:+.3f}; newly below -0.3: {newly}')
