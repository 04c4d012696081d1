"""sphinx-gallery image scraper for the figures rsf-sweep draws without pyplot, and the
gallery's thumbnails.

``sweep.plot_*`` return :class:`matplotlib.figure.Figure` objects that pyplot never
sees, so sphinx-gallery's matplotlib scraper finds none. This one saves every Figure
bound to a name in the example's namespace that it has not saved yet.

Thumbnails: sphinx-gallery shrinks an example's first figure, whole, to 400 × 280
pixels, so a two- or three-panel figure becomes unreadable lines. Here the first
figure of each example is drawn again (a copy) with its first panel about 4.5 by 3
inches and no titles, cropped to that panel and written to ``docs/generated/thumbs/``;
after the gallery is generated, :func:`replace_thumbnails` puts each into the
gallery's thumbnail file, centred on white.

Figures are written as plain ``image`` directives, one below the other, with the
figure's titles as their alternative text (sphinx-gallery's own ``image-sg`` would
put several side by side, with the file's name as the text, and is a node of its
own, which ``sweep_figures`` cannot make a link to the full-size image).
"""

import pickle
from pathlib import Path

from matplotlib.figure import Figure
from sphinx_gallery.scrapers import matplotlib_scraper

DOCS = Path(__file__).resolve().parents[1]
THUMBS = DOCS / "generated" / "thumbs"
#: Width of the thumbnail's panel (inches) and its resolution: 10 pt type is ~12 px.
PANEL_WIDTH = 4.5
PANEL_HEIGHT = 3.0
THUMB_DPI = 90


def save_thumbnail(fig, stem):
    """The first panel of a copy of ``fig``, without titles, resized to about
    ``PANEL_WIDTH`` by ``PANEL_HEIGHT`` inches (the thumbnail's shape), as a PNG."""
    copy = pickle.loads(pickle.dumps(fig))
    ax = copy.axes[0]
    ax.set_title("")
    if copy._suptitle is not None:
        copy._suptitle.set_text("")
    copy.draw_without_rendering()
    box = ax.get_position()
    width, height = copy.get_size_inches()
    copy.set_size_inches(width * PANEL_WIDTH / (box.width * width),
                         height * PANEL_HEIGHT / (box.height * height))  # fmt: skip
    copy.draw_without_rendering()
    box = ax.get_tightbbox().transformed(copy.dpi_scale_trans.inverted()).padded(0.05)
    THUMBS.mkdir(parents=True, exist_ok=True)
    copy.savefig(THUMBS / f"{stem}.png", dpi=THUMB_DPI, bbox_inches=box)


def alt_text(fig, stem):
    """A figure's titles (its suptitle, else its panels' titles), or the example's name."""
    titles = [fig._suptitle.get_text()] if fig._suptitle is not None else []
    titles = [t for t in titles if t] or [ax.get_title() for ax in fig.axes if ax.get_title()]
    text = "; ".join(titles) or stem.removeprefix("plot_").replace("_", " ")
    return " ".join(text.split())


def image_rst(path, alt, src_dir):
    """An ``image`` directive for a figure written to ``path``, under the source folder."""
    uri = Path(path).relative_to(src_dir).as_posix()
    return f"\n.. image:: /{uri}\n   :alt: {alt}\n   :class: sphx-glr-single-img\n\n"


def scrape_figures(block, block_vars, gallery_conf, **kwargs):
    """Save the example's new Figures (and any pyplot figures) as PNG; their reST."""
    paths, rst = [], ""
    stem = Path(block_vars["src_file"]).stem
    for value in list(block_vars["example_globals"].values()):
        if isinstance(value, Figure) and not getattr(value, "_sweep_scraped", False):
            path = next(block_vars["image_path_iterator"])
            value.savefig(path, dpi=90, bbox_inches="tight")
            value._sweep_scraped = True
            if len(block_vars["image_path_iterator"]) == 1 and not paths:
                save_thumbnail(value, stem)
            paths.append(path)
            rst += image_rst(path, alt_text(value, stem), gallery_conf["src_dir"])
    return rst + matplotlib_scraper(block, block_vars, gallery_conf, **kwargs)


def _get_sg_image_scraper():
    return scrape_figures


def replace_thumbnails(app):
    """Each gallery thumbnail from its example's first panel (``THUMBS``), when made."""
    from PIL import Image

    conf = app.config.sphinx_gallery_conf
    width, height = conf.get("thumbnail_size", (400, 280))
    thumb_dir = DOCS / conf["gallery_dirs"] / "images" / "thumb"
    for panel in sorted(THUMBS.glob("*.png")):
        target = thumb_dir / f"sphx_glr_{panel.stem}_thumb.png"
        if not target.exists():
            continue
        image = Image.open(panel).convert("RGB")
        image.thumbnail((width, height), Image.Resampling.LANCZOS)
        canvas = Image.new("RGB", (width, height), "white")
        canvas.paste(image, ((width - image.width) // 2, (height - image.height) // 2))
        canvas.save(target)


def setup(app):
    # after sphinx-gallery has run the examples and written its thumbnails (priority 500)
    app.connect("builder-inited", replace_thumbnails, priority=900)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
