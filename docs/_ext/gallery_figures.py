"""A sphinx-gallery image scraper for the matplotlib Figures an example holds in its variables
outside pyplot: lagrgen's plots (`sol.plot()`, `plot_series`, ...) draw on their own Agg canvas,
which sphinx-gallery's matplotlib scraper, reading pyplot's figures, does not see. Each such
figure is shown once, after the block that made it. Named in conf.py's sphinx_gallery_conf as
"gallery_figures" (sphinx-gallery calls `_get_sg_image_scraper`)."""
from sphinx_gallery.scrapers import figure_rst


def held_figures(block, block_vars, gallery_conf, **kwargs):
    """Save the not yet shown Figures without a pyplot manager in the example's variables; their
    reStructuredText."""
    from matplotlib.figure import Figure
    paths = []
    for value in list(block_vars["example_globals"].values()):
        if isinstance(value, Figure) and value.canvas.manager is None \
                and not getattr(value, "_shown_in_gallery", False):
            value._shown_in_gallery = True
            path = next(block_vars["image_path_iterator"])
            value.savefig(path)
            paths.append(path)
    return figure_rst(paths, gallery_conf["src_dir"])


def _get_sg_image_scraper():
    return held_figures
