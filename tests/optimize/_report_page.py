"""Reading report.html back (tests only): the summary cells, the pictures, the scripts, the scene."""

import json
from html.parser import HTMLParser

from contopt.io.webview import SCENE_ID


class ReportPage(HTMLParser):
    """The parts of report.html the tests check.

    cells : {data-key: (value read from data-value, shown text)}
    pictures : {data-picture: src}; scripts : [(attrs, text)]
    references : every src/href value the page loads and whether any is by URL (``external``);
    links : the href of every ``<a>`` (a link the user follows, not a load)
    """

    def __init__(self, text: str):
        super().__init__(convert_charrefs=True)
        self.cells, self.pictures, self.scripts, self.references, self.links = {}, {}, [], [], []
        self._cell = self._script = None
        self.feed(text)
        self.close()

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "a":
            self.links += [attrs["href"]] if "href" in attrs else []
        else:
            self.references += [attrs[k] for k in ("src", "href") if k in attrs]
        if tag == "td" and "data-key" in attrs:
            self._cell = [attrs["data-key"], json.loads(attrs["data-value"]), ""]
        elif tag == "img" and "data-picture" in attrs:
            self.pictures[attrs["data-picture"]] = attrs["src"]
        elif tag == "script":
            self._script = [attrs, ""]

    def handle_data(self, data):
        if self._cell is not None:
            self._cell[2] += data
        if self._script is not None:
            self._script[1] += data

    def handle_endtag(self, tag):
        if tag == "td" and self._cell is not None:
            key, value, text = self._cell
            self.cells[key] = (value, text)
            self._cell = None
        elif tag == "script" and self._script is not None:
            self.scripts.append(tuple(self._script))
            self._script = None

    @property
    def external(self) -> list[str]:
        """References that are no data: URI (the page must load nothing)."""
        return [r for r in self.references if not r.startswith("data:")]

    def scene(self) -> dict | None:
        """The embedded scene data (None when the page has no 3D view)."""
        for attrs, text in self.scripts:
            if attrs.get("id") == SCENE_ID:
                return json.loads(text)  # JSON reads the escaped "<\/" of the page as "</"
        return None
