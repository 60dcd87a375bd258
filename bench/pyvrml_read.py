"""Read one VRML file with PyVRML97 (the bench's and scripts/wild_vrml.py's peer): exit 0 when
it reads all of it, else the offset where it stopped. Usage: python pyvrml_read.py FILE"""

import sys

from vrml.vrml97 import parseprocessor, parser

path = sys.argv[1]
text = open(path, "rb").read().decode("utf-8")
ok, children, end = parser.buildParser().parse(
    text, processor=parseprocessor.ParseProcessor(baseURI=path)
)
if not ok or end != len(text):
    sys.exit(f"stopped at offset {end} of {len(text)}")
