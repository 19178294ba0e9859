#!/usr/bin/env python3
# Where a charge's learning stopped: for each CC charge of an estimate (estimates.csv), the seconds
# before the charge's end of the first tick with kInnovationRejected (status bit 18: the stop
# conditions report it: the trusted span's end, and --innovation-reject on).
# Usage: scripts/stop_position.py OUT/CELL-SEED/est/estimates.csv
import csv, sys
path = sys.argv[1]
rows = list(csv.DictReader(open(path)))
charges = []; cur = None
for r in rows:
    st = int(r['status']); cc = r['mode'] == 'cc_charge'
    if cc:
        if cur is None: cur = {'start': float(r['t_s']), 'stop': None, 'cycle': r['cycle']}
        cur['end'] = float(r['t_s'])
        if cur['stop'] is None and st & (1 << 18): cur['stop'] = float(r['t_s'])
    elif cur is not None:
        charges.append(cur); cur = None
if cur: charges.append(cur)
for c in charges:
    s = 'none' if c['stop'] is None else '%.0f s before end' % (c['end'] - c['stop'])
    print('cycle', c['cycle'], 'CC charge %.0f s' % (c['end'] - c['start']), 'stop', s)
