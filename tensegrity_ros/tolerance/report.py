"""A tolerance study's report: the text table and the PNG figures (matplotlib, Agg).

Input is :meth:`.result.ToleranceResult.summary` (and the result itself for the
histograms); nothing here computes a statistic.
"""
from __future__ import annotations

import math

import numpy as np

#: Figures not drawn as histograms (codes) -- counted in the text instead.
_SKIP = ('status',)


def _g(v, digits=6):
    return 'nan' if v is None or (isinstance(v, float) and math.isnan(v)) else f'{v:.{digits}g}'


def report_text(s):
    """The summary as a few tables of text."""
    lines = _head_lines(s) + _quantile_lines(s)
    if s['kinds']:
        lines += ['', 'counts:']
        for name, counts in s['kinds'].items():
            lines.append(f'  {name}: ' + ', '.join(f'{k} {v}' for k, v in counts.items()))
    if s['probabilities']:
        lines += ['', 'probabilities:']
        for name, p in s['probabilities'].items():
            lo, hi = p['interval']
            lines.append(f'  {name}: {p["events"]}/{p["trials"]} = {_g(p["p"], 4)}, '
                         f'{100 * p["confidence"]:g} % interval [{_g(lo, 4)}, {_g(hi, 4)}] '
                         f'({p["method"]})')
    return '\n'.join(lines + _sensitivity_lines(s) + _worst_lines(s)) + '\n'


def _head_lines(s):
    e = s['engine']
    status = ', '.join(f'{k}: {v}' for k, v in s['status'].items())
    tolerances = ', '.join(
        f'{t["parameter"]} = {_g(t["nominal"])}'
        + (f' +- {t["spec"]}' if t['distribution'] == 'uniform' else f', {t["spec"]}')
        for t in s['tolerances'])
    return [f'tolerance study: question {s["question"]}, {s["samples"]} samples '
            f'({s["sampler"]}, seed {s["seed"]}), {s["valid"]} answered'
            + ('' if s['valid'] == s['samples'] else f' ({status})'),
            f'engine: {e["engine"]}, {e["chunks"]} chunks of {s["chunk"]}: '
            f'{e["seconds"]:.2f} s ({e["samples_per_second"]:.0f} samples/s; '
            f'start-up {e["startup_seconds"]:.2f} s; overhead {100 * e["overhead"]:.1f} %)',
            f'tolerances: {tolerances}']


def _quantile_lines(s):
    if not s['figures']:
        return []
    width = max(len(n) for n in s['figures'])
    levels = next(iter(s['figures'].values()))['quantiles']
    head = ['figure'.ljust(width), 'count'.rjust(6)] + [q.rjust(12) for q in levels]
    lines = ['', 'quantiles:', '  ' + ' '.join(head)]
    for name, f in s['figures'].items():
        lines.append('  ' + ' '.join([name.ljust(width), str(f['count']).rjust(6)]
                                     + [_g(v, 8).rjust(12) for v in f['quantiles'].values()]))
    return lines


def _sensitivity_lines(s):
    sens = s['sensitivity']
    labels = [t['parameter'] for t in s['tolerances']]
    lines = []
    for key, what in (('figures', 'with each parameter'),
                      ('error_size', 'with the size of its error |x - nominal| (even '
                                     'effects)')):
        table = sens.get(key) or {}
        if not table:
            continue
        width = max(len(n) for n in table)
        lines += ['', f'sensitivity: {sens["measure"]} {what}; |r| < '
                      f'{sens["noise_level"]:.3f} is noise:',
                  '  ' + ' '.join(['figure'.ljust(width)] + [lab.rjust(9) for lab in labels])]
        for name, r in table.items():
            lines.append('  ' + ' '.join([name.ljust(width)]
                                         + [('-' if r[lab] is None else f'{r[lab]:+.3f}')
                                            .rjust(max(9, len(lab))) for lab in labels]))
    return lines


def _worst_lines(s):
    if not s['worst']:
        return []
    lines = ['', f'worst samples (by {s["worst"][0]["figure"]}):']
    for w in s['worst']:
        values = ', '.join(f'{k}={_g(v, 10)}' for k, v in w['parameters'].items())
        lines.append(f'  #{w["index"]}: {w["figure"]} = {_g(w["value"], 8)} '
                     f'({w["status"]}); {values}')
        if w.get('config'):
            lines.append(f'    parameter file {w["config_file"]}: the "config" text of the '
                         f'JSON report (--replay-dir writes it)')
        lines += [f'    {cmd}' for cmd in w['replay']]
    return lines


def _new_figure(size):
    import matplotlib
    matplotlib.use('Agg', force=False)
    from matplotlib.figure import Figure
    return Figure(figsize=size, dpi=100, layout='constrained')


def plot_histograms(result, path):
    """One histogram per figure that varies (valid samples), quantiles 5/50/95 % marked."""
    ok = result.valid()
    names = []
    for name, values in result.figures.items():
        v = values[ok]
        v = v[np.isfinite(v)]
        if name not in _SKIP and v.size and np.ptp(v) > 0:
            names.append((name, v))
    cols = min(3, max(1, len(names)))
    rows = max(1, math.ceil(len(names) / cols))
    fig = _new_figure((4.0 * cols, 2.8 * rows))
    summary = result.summary()
    for k, (name, v) in enumerate(names):
        ax = fig.add_subplot(rows, cols, k + 1)
        ax.hist(v, bins=min(60, max(10, int(math.sqrt(v.size)))), color='#4878a8')
        q = summary['figures'].get(name, {}).get('quantiles')
        if q:
            for label in ('5%', '50%', '95%'):
                ax.axvline(q[label], color='k', lw=0.8, ls='--' if label != '50%' else '-')
        ax.set_title(name, fontsize=9)
        ax.tick_params(labelsize=7)
    if not names:
        fig.add_subplot().text(0.5, 0.5, 'no figure varies', ha='center')
    fig.suptitle(f'tolerance study ({summary["question"]}): {summary["valid"]} samples; '
                 f'dashed 5 / 95 %, solid median', fontsize=10)
    fig.savefig(path, format='png')
    return path


def plot_sensitivity(summary, path):
    """Grouped horizontal bars: rank correlation of each figure with each parameter (left)
    and with the size of each parameter's error (right: effects even in the error)."""
    sens = summary['sensitivity']
    figures = list(sens['figures'])
    labels = [t['parameter'] for t in summary['tolerances']]
    fig = _new_figure((11.0, 1.2 + 0.3 * max(1, len(figures)) * max(1, len(labels)) ** 0.7))
    height = 0.8 / max(1, len(labels))
    y = np.arange(len(figures))
    noise = sens['noise_level']
    for k, (key, title) in enumerate((('figures', 'with the parameter'),
                                      ('error_size', 'with |parameter - nominal|'))):
        ax = fig.add_subplot(1, 2, k + 1)
        table = sens.get(key) or {}
        for j, label in enumerate(labels):
            r = [(table.get(f) or {}).get(label) for f in figures]
            ax.barh(y + j * height, [0.0 if v is None else v for v in r], height,
                    label=label if k == 0 else None)
        for x in (-noise, noise):
            ax.axvline(x, color='grey', lw=0.8, ls=':')
        ax.set_yticks(y + 0.4 - height / 2, figures if k == 0 else [''] * len(figures),
                      fontsize=8)
        ax.set_xlim(-1, 1)
        ax.invert_yaxis()
        ax.set_xlabel(f'Spearman rank correlation {title}', fontsize=8)
        if k == 0 and labels:
            ax.legend(fontsize=7, loc='best')
    fig.suptitle(f'sensitivity ({summary["question"]}, {summary["valid"]} samples; dotted: '
                 f'noise level)', fontsize=10)
    fig.savefig(path, format='png')
    return path
