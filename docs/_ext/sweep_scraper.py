"""sphinx-gallery image scraper for the figures rsf-sweep draws without pyplot.

``sweep.plot_*`` return :class:`matplotlib.figure.Figure` objects that pyplot never
sees, so sphinx-gallery's matplotlib scraper finds none. This one saves every Figure
bound to a name in the example's namespace that it has not saved yet.
"""

from matplotlib.figure import Figure
from sphinx_gallery.scrapers import figure_rst, matplotlib_scraper


def scrape_figures(block, block_vars, gallery_conf, **kwargs):
    """Save the example's new Figures (and any pyplot figures) as PNG; their reST."""
    paths = []
    for value in list(block_vars["example_globals"].values()):
        if isinstance(value, Figure) and not getattr(value, "_sweep_scraped", False):
            path = next(block_vars["image_path_iterator"])
            value.savefig(path, dpi=90, bbox_inches="tight")
            value._sweep_scraped = True
            paths.append(path)
    rst = figure_rst(paths, gallery_conf["src_dir"]) if paths else ""
    return rst + matplotlib_scraper(block, block_vars, gallery_conf, **kwargs)


def _get_sg_image_scraper():
    return scrape_figures
