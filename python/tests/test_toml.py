"""The TOML writer: every string reads back as itself (through tomllib,
Python 3.11+), hostile characters included."""

import sys
import unittest

from nmbake import _toml

try:
    import tomllib
except ImportError:  # Python < 3.11: the reading-back tests are skipped
    tomllib = None

HOSTILE = [
    "plain",
    'a "quoted" name',
    "back\\slash\\",
    "new\nline\r\n",
    "tab\there",
    "nul\x00bell\x07esc\x1bdel\x7f",
    "unicode é ü 漢字 🙂",
    "'single' and \"\"\" triple",
    "",
    "trailing backslash \\",
]


class TomlStringTest(unittest.TestCase):
    def test_escapes_what_toml_forbids(self):
        self.assertEqual(_toml.string('a"b'), '"a\\"b"')
        self.assertEqual(_toml.string("a\\b"), '"a\\\\b"')
        self.assertEqual(_toml.string("a\nb"), '"a\\nb"')
        self.assertEqual(_toml.string("\x00\x7f"), '"\\u0000\\u007F"')
        self.assertEqual(_toml.string("é"), '"é"')

    def test_lone_surrogate_is_refused(self):
        with self.assertRaises(ValueError):
            _toml.string("bad\udcff")

    def test_values(self):
        self.assertEqual(_toml.value(True), "true")
        self.assertEqual(_toml.value(3), "3")
        self.assertEqual(_toml.value(0.25), "0.25")
        self.assertEqual(_toml.value(1e-5), "1e-05")
        self.assertEqual(_toml.value(["a", "b"]), '["a", "b"]')
        self.assertEqual(_toml.value({"path": "x.exr", "format": "exr-half"}),
                         '{ path = "x.exr", format = "exr-half" }')
        with self.assertRaises(TypeError):
            _toml.value(object())
        with self.assertRaises(ValueError):
            _toml.value(2**63)

    def test_keys(self):
        self.assertEqual(_toml.key("max_memory"), "max_memory")
        self.assertEqual(_toml.key("a b"), '"a b"')

    @unittest.skipIf(tomllib is None, "tomllib needs Python 3.11 (this is %s)" % sys.version.split()[0])
    def test_round_trip_through_tomllib(self):
        entries = {"s%d" % i: text for i, text in enumerate(HOSTILE)}
        entries.update({"list": HOSTILE, "n": -7, "x": 1.5e300, "yes": False, "weird key \"é\"": "v"})
        text = _toml.table("[[bake]]", entries)
        back = tomllib.loads(text)["bake"][0]
        self.assertEqual(back, entries)


if __name__ == "__main__":
    unittest.main()
