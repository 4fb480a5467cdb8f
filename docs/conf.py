# Sphinx configuration of the documentation site (`bash .ci/bootstrap docs` -> build/docs/).
# docs/build_docs.py copies docs/ into a work directory, adds the pages generated at build
# time (cli.md: every subcommand's --help; api/cpp.md: one section per installed header;
# scenes.md: reference-data/scenes/README.md)
# and runs Doxygen (C++ and C headers -> XML for Breathe) and Sphinx there.
import logging
import os
import re

project = "kneedyn"
author = "kneedyn developers"
release = os.environ.get("KNEEDYN_DOCS_VERSION", "")
version = release

extensions = [
    "myst_parser",            # docs/*.md
    "breathe",                # the C++ headers (Doxygen XML)
    "sphinx.ext.autodoc",     # the Python module's docstrings
]
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
master_doc = "index"
exclude_patterns = ["_build"]
# Headings down to ### get labels "file.md#slug", for links from the docstrings, e.g.
# :ref:`summary.json <outputs.md#summaryjson-schema_version-2>`.
myst_heading_anchors = 3

breathe_projects = {"kneedyn": os.environ.get("KNEEDYN_DOXYGEN_XML", "doxygen/xml")}
breathe_default_project = "kneedyn"
breathe_domain_by_extension = {"hpp": "cpp", "h": "c"}  # kneedyn/problem.h is C
# The headers' comments are plain //; the Doxygen input filter (build_docs.py) turns them
# into documentation, so a member's description is the comment above it in the header.

# `name` in a docstring is code (what the docstrings mean by it), not emphasis.
default_role = "literal"
autodoc_member_order = "bysource"
autodoc_default_options = {"members": True, "undoc-members": True}

# Option names in prose ("--help") keep their two hyphens.
smartquotes = False

html_theme = "alabaster"
html_title = "kneedyn"
html_show_sourcelink = False


class _NamespaceInEveryHeader(logging.Filter):
    """Breathe declares namespace kneedyn once per header page section; Sphinx's C++ domain
    calls the repeats duplicates. Only that warning is dropped (with -W every other fails)."""

    def filter(self, record):
        text = record.getMessage()
        return not (text.startswith("Duplicate C++ declaration") and "cpp:type:: kneedyn'" in text)


class _TypedefOfSameNamedEnum(logging.Filter):
    """`typedef enum kneedyn_status {...} kneedyn_status;` (kneedyn/problem.h) declares the enum
    and its typedef under one name; Sphinx's C domain calls the second a duplicate. Only that
    warning is dropped."""

    def filter(self, record):
        text = record.getMessage()
        return not (text.startswith("Duplicate C declaration") and re.search(r"c:type:: enum (\w+) \1'", text))


def setup(app):
    logging.getLogger("sphinx.sphinx.domains.cpp").addFilter(_NamespaceInEveryHeader())
    logging.getLogger("sphinx.sphinx.domains.c").addFilter(_TypedefOfSameNamedEnum())
