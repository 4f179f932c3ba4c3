"""The page ``dvc plots show`` fills, with its scripts inlined: the plots render offline
(README, "Plots").

DVC writes its plots into an HTML page whose ``<head>`` loads Vega, Vega-Lite and
Vega-Embed from a CDN (``dvc_render.vega.VegaRenderer.SCRIPTS``), so without a network the
page is blank. DVC takes another page from the ``plots.html_template`` setting
(``.dvc/config``): it puts the plots where the page says ``{plot_divs}``, the refresh tag
at ``{refresh_tag}`` and the CDN script tags at ``{scripts}``. The page built here has no
``{scripts}``, so no CDN tag goes in; the three libraries are inlined instead, as the
``vl-convert-python`` package (pinned in pyproject.toml) bundles them: nothing is
fetched when the page is written or opened.

The ``plots_page`` stage writes it as ``data/plots/page.html``, git-tracked like the plot
tables, so a fresh clone renders its plots before any ``dvc repro``.
"""

from __future__ import annotations

from importlib.metadata import version

__all__ = ["PLACEHOLDERS", "VEGA_LITE", "page_html"]

#: the Vega-Lite the bundle carries: DVC's templates are written for Vega-Lite 5
VEGA_LITE = "5.21"
#: what DVC replaces in the page (``dvc_render.html.HTML``); ``{scripts}`` is left out
PLACEHOLDERS = ("{plot_divs}", "{refresh_tag}")

#: what the bundle runs: the three libraries as globals, for DVC's ``vegaEmbed(...)`` calls
_GLOBALS = "window.vegaEmbed = vegaEmbed; window.vegaLite = vegaLite; window.vega = vega;"

_PAGE = """<!DOCTYPE html>
<html>
<head>
    <meta charset="utf-8">
    {refresh_tag}
    <title>TATTOTRONIX plots</title>
    <!-- {versions}: inlined, nothing is fetched (tattotronix/report/plotpage.py) -->
    <script type="text/javascript">
__BUNDLE__
    </script>
    <style>
        body { font-family: sans-serif; margin: 16px; }
        table { border-spacing: 15px; }
    </style>
</head>
<body>
    {plot_divs}
</body>
</html>
"""


def page_html() -> str:
    """The page: DVC's placeholders, and Vega, Vega-Lite and Vega-Embed inlined from the
    installed ``vl-convert-python`` (the same bytes for the same version).

    Raises:
        ValueError: the bundle holds something that would break the page (a
            ``</script``, or one of DVC's placeholders).
    """
    import vl_convert

    bundle = vl_convert.javascript_bundle(_GLOBALS, vl_version=VEGA_LITE)
    for bad in ("</script", "<!--", "{scripts}", *PLACEHOLDERS):
        if bad in bundle:
            raise ValueError(f"the Vega bundle of vl-convert-python holds {bad!r}: it cannot "
                             "be inlined in the page as it is")
    versions = (f"Vega {vl_convert.get_vega_version()}, Vega-Lite {VEGA_LITE}, Vega-Embed "
                f"{vl_convert.get_vega_embed_version()} from vl-convert-python "
                f"{version('vl-convert-python')}")
    return _PAGE.replace("{versions}", versions).replace("__BUNDLE__", bundle)
