"""The matplotlib figure every PNG of the package is drawn on (Agg: no display);
like every plotting function here, it imports matplotlib only when it draws.
"""


def new_figure(size):
    """A constrained-layout Figure of ``size`` inches at 100 dpi, on the Agg backend."""
    import matplotlib
    matplotlib.use('Agg', force=False)
    from matplotlib.figure import Figure
    return Figure(figsize=size, dpi=100, layout='constrained')
