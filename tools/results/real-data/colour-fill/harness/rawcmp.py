import re, sys, statistics as s
def rows(p):
    d = {}
    for line in open(p):
        c = [x.strip() for x in line.split("|")]
        if len(c) > 6 and re.match(r"^[a-z0-9]", c[1] or "") and c[2][:1].isdigit() and c[1] not in d:
            d[c[1]] = (float(c[2]), float(c[3]))
    return d
h = rows(sys.argv[1]); others = [rows(p) for p in sys.argv[2:]]
print("n", len(h), "head %+.3f" % s.mean([h[k][1] - h[k][0] for k in h]),
      " ".join("%s %+.3f (worst %+.3f, LDR shift %+.3f)" % (p.split('/')[-1], s.mean([o[k][1] - h[k][0] for k in h]),
               min(o[k][1] - h[k][0] for k in h), s.mean([o[k][0] - h[k][0] for k in h])) for p, o in zip(sys.argv[2:], others)))
for k in h:
    g = [o[k][1] - h[k][0] for o in others]
    if max(g) - min(g) > 0.1 or min(g) < h[k][1] - h[k][0] - 0.05:
        print("  %-40s head %+.2f " % (k[:40], h[k][1] - h[k][0]) + " ".join("%+.2f" % x for x in g))
