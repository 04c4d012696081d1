"""The landing page's figure, computed when the site is built.

The packaged example ``quasidynamic`` (one block, driving stiffness K/W × radiation
damping η/W) is the smallest shipped sweep whose phase diagram has all three regimes:
steady above the critical stiffness, stick-slip below it, runaway without damping.
It runs in seconds once its kernel is compiled (the gallery compiles the same one),
so the page shows what the current code computes instead of a picture that could go
stale. One panel, large type, so that it stays readable at the page's width.
"""

from pathlib import Path

#: Where the figure is written (under docs/generated/, which is not committed).
FIGURE = Path(__file__).resolve().parents[1] / "generated" / "landing_regimes.png"
EXAMPLE = "quasidynamic"


def make_landing_figure(app):
    import matplotlib
    from matplotlib.figure import Figure

    import sweep

    ds = sweep.run(EXAMPLE, progress=False)
    with matplotlib.rc_context({"font.size": 14, "legend.fontsize": 13}):
        fig = Figure(figsize=(8.0, 5.0), layout="constrained")
        ax = fig.subplots()
        sweep.plot_variable(ds, "regime", ax=ax)
        ax.set_title(f"Regime of each of the {ds['regime'].size} runs of the example "
                     f"'{EXAMPLE}'", fontsize=14)  # fmt: skip
        for text in ax.get_legend().get_texts():
            text.set_fontsize(13)
        FIGURE.parent.mkdir(parents=True, exist_ok=True)
        sweep.save_figure(fig, FIGURE, dpi=110)


def setup(app):
    app.connect("builder-inited", make_landing_figure)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
