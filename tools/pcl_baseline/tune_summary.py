#!/usr/bin/env python3
"""Summaries of tools/pcl_baseline/tune.sh's per-frame CSVs (OUT_DIR/<tag>.<set>.csv).

  tune_summary.py OUT_DIR best-learn      tag of the best LCCP point on mosd-learn
  tune_summary.py OUT_DIR options TAG     clutterseg-pcl-baseline options of a tag
  tune_summary.py OUT_DIR report          grid, per-category and leave-one-category-out tables

Score of a set of frames: mean over frames of (WOv + F1) / 2 (mosd-parts for mOSD, or the
convention tune.sh was run with).
"""
import csv
import glob
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '..'))
from mosd_categories import CATEGORIES, category  # noqa: E402

MOSD = CATEGORIES
SYNTH = (('synth7', 'synthetic rooms s7'), ('synth101', 'synthetic rooms s101'),
         ('p2001', 'synthetic piles s2001'), ('p2002', 'synthetic piles s2002'))




def rows(out, tag, s):
    path = os.path.join(out, '%s.%s.csv' % (tag, s))
    if not os.path.exists(path):
        return None
    return [r for r in csv.DictReader(open(path)) if r['wov'] != '']


def mean(rs, key):
    return sum(float(r[key]) for r in rs) / len(rs)


def score(rs):
    return sum((float(r['wov']) + float(r['f1'])) / 2 for r in rs) / len(rs)


def lccp_tags(out):
    tags = set()
    for p in glob.glob(os.path.join(out, 'lccp_*.learn.csv')):
        tag = os.path.basename(p)[:-len('.learn.csv')]
        if os.path.exists(os.path.join(out, tag + '.clutter.csv')):
            tags.add(tag)
    return sorted(tags)


def options(tag):
    f = dict(kv.split('-', 1) for kv in tag[len('lccp_'):].split('_'))
    o = ['--concavity', f['con'], '--voxel', f['vox'], '--seed', f['seed'], '--color', '0',
         '--spatial', '1', '--normal', f['nrm']]
    if f['ext'] == 'off':
        o.append('--no-extended')
    if f['san'] == 'off':
        o.append('--no-sanity')
    if f['sct'] == 'on':
        o.append('--single-camera-transform')
    return ' '.join(o)


def mosd_frames(out, tag):
    return rows(out, tag, 'learn') + rows(out, tag, 'clutter')


def best_learn(out):
    return max(lccp_tags(out), key=lambda t: (score(rows(out, t, 'learn')), t))


def cell(rs, merged=False):
    if not rs:
        return 'n/a'
    c = '%.4f / %.4f' % (mean(rs, 'wov'), mean(rs, 'f1'))
    return c


def pr(rs):
    return '%.4f / %.4f' % (mean(rs, 'precision'), mean(rs, 'recall')) if rs else 'n/a'


def report(out):
    tags = lccp_tags(out)
    ranked = sorted(tags, key=lambda t: -score(rows(out, t, 'learn')))
    best = ranked[0]
    print('## Grid on mosd-learn (%d points; score = mean (WOv + F1) / 2)\n' % len(tags))
    print('| rank | setting | score | WOv / F1 | precision / recall | segments/frame |')
    print('|---|---|---|---|---|---|')
    for i, t in enumerate(ranked):
        if i < 10 or t == best:
            L = rows(out, t, 'learn')
            print('| %d | `%s` | %.4f | %s | %s | %.1f |' % (i + 1, t, score(L), cell(L), pr(L),
                                                          mean(L, 'segments')))
    print('\nchosen: `%s` -> `%s`\n' % (best, options(best)))

    print('## Per category (WOv / F1 ; precision / recall)\n')
    research = 'lccp_ext-off_con-20_san-on_sct-on_vox-0.0075_seed-0.03_nrm-4'
    entries = [('clutterseg defaults', 'clutterseg_defaults'), ('PCL LCCP best on learn', best),
               ('PCL LCCP, docs/results.md setting (7.5 mm, 20 deg)', research)]
    entries += [('PCL LCCP `%s`' % t, t) for t in tags
                if t not in (best, research) and rows(out, t, 'synth7') is not None]
    head = ['learn'] + list(MOSD[:4]) + ['clutter'] + list(MOSD[4:]) + ['clutter merged'] + \
        [n for _, n in SYNTH]
    print('| configuration | metric | ' + ' | '.join(head) + ' |')
    print('|---|---|' + '---|' * len(head))
    for name, tag in entries:
        L, C = rows(out, tag, 'learn'), rows(out, tag, 'clutter')
        if L is None or C is None:
            continue
        groups = [L] + [[r for r in L if category(r['frame']) == c] for c in MOSD[:4]] + [C] + \
            [[r for r in C if category(r['frame']) == c] for c in MOSD[4:]]
        synth = [rows(out, tag, s) for s, _ in SYNTH]
        merged = str(sum(int(r['under_segmented']) for r in C))
        print('| %s | WOv / F1 | ' % name + ' | '.join([cell(g) for g in groups] + [merged] +
                                                       [cell(g) for g in synth]) + ' |')
        print('| %s | precision / recall | ' % name +
              ' | '.join([pr(g) for g in groups] + [''] + [pr(g) for g in synth]) + ' |')
        print('| %s | synthetic merged | ' % name + ' | '.join([''] * 9) + ' | ' +
              ' | '.join(str(sum(int(r['under_segmented']) for r in g)) if g else 'n/a'
                         for g in synth) + ' |')

    print('\n## Leave one category out, PCL (best grid point on the other five mOSD categories,'
          ' frames pooled)\n')
    print('| held out | frames | chosen on the other five | score there | held-out WOv / F1 |'
          ' held-out precision / recall | merged | best-on-learn point held-out WOv / F1 |')
    print('|---|---|---|---|---|---|---|---|')
    for c in MOSD:
        def split(t, inside):
            return [r for r in mosd_frames(out, t) if (category(r['frame']) == c) == inside]
        pick = max(tags, key=lambda t: (score(split(t, False)), t))
        held = split(pick, True)
        print('| %s | %d | `%s` | %.4f | %s | %s | %d | %s |' % (
            c, len(held), pick, score(split(pick, False)), cell(held), pr(held),
            sum(int(r['under_segmented']) for r in held), cell(split(best, True))))


def main():
    out, mode = sys.argv[1], sys.argv[2]
    if mode == 'best-learn':
        print(best_learn(out))
    elif mode == 'options':
        print(options(sys.argv[3]))
    elif mode == 'report':
        report(out)
    else:
        sys.exit('unknown mode ' + mode)


if __name__ == '__main__':
    main()
