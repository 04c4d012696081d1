"""Figures wider than the page link to their full-size image.

A figure of several panels (the refined maps, the N-block and two-block phase
diagrams, the gallery's) is drawn 1100 to 1600 pixels wide and scaled down to the
text column (furo: 46em, about 740 pixels), where its labels are too small to read.
Every local image wider than :data:`COLUMN` pixels is made a link to its own copy in
``_images/``, as Sphinx does for images given a width (``html_scaled_image_link``),
so a click opens it at full size; the style sheet shows a zoom cursor over it.
Thumbnails and narrower images are left as they are.
"""

from docutils import nodes
from sphinx.util.osutil import relative_uri

#: Width of furo's text column in pixels (46em at 16 px): wider images are scaled down.
COLUMN = 740


def pixel_width(path):
    """The width of an image file in pixels, or 0 if it cannot be read."""
    from PIL import Image

    try:
        with Image.open(path) as image:
            return image.width
    except OSError:
        return 0


def link_wide_images(app, doctree, docname):
    """Wrap each image wider than the text column in a link to its full-size copy."""
    if app.builder.format != "html":
        return
    imgpath = relative_uri(app.builder.get_target_uri(docname), app.builder.imagedir)
    for image in list(doctree.findall(nodes.image)):
        uri = image.get("candidates", {}).get("*", image["uri"])
        if isinstance(image.parent, nodes.reference) or uri not in app.env.images:
            continue
        if pixel_width(app.srcdir / uri) <= COLUMN:
            continue
        link = nodes.reference(
            "", "", internal=True, refuri=f"{imgpath}/{app.env.images[uri][1]}",
            reftitle="the figure at full size", classes=["full-size"],
        )  # fmt: skip
        image.replace_self(link)
        link.append(image)


def setup(app):
    app.connect("doctree-resolved", link_wide_images)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
