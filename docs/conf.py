"""Sphinx configuration of the orbitflex documentation site (built by docs/build.sh).

Pages are Markdown (MyST); tutorials and the gallery are jupytext ``py:percent`` files that the
build executes (MyST-NB). The API reference is autodoc over the installed package: the text comes
from the compiled core's docstrings, the typed signatures from its stub ``_core.pyi``. MathJax is
served from the site itself, so the pages work offline.
"""

import ast
import importlib.metadata
import re
import shutil
from pathlib import Path

import orbitflex

HERE = Path(__file__).resolve().parent

project = "orbitflex"
author = "The orbitflex developers"
copyright = "the orbitflex developers; MIT OR Apache-2.0"
release = orbitflex.__version__
version = release

extensions = ["myst_nb", "sphinx.ext.autodoc", "sphinx.ext.mathjax"]

# Only the tutorials and the gallery are notebooks; every other .py file here is not a page.
exclude_patterns = ["_build", "conf.py", "build.sh", "**/.ipynb_checkpoints", "_ext"]
nb_custom_formats = {".py": ["jupytext.reads", {"fmt": "py:percent"}]}

# Every notebook runs on every build, in a temporary folder; a failing cell is a warning (with its
# traceback and a report under _build/html/reports), which -W turns into a failed build after
# every other problem has been listed too.
nb_execution_mode = "force"
nb_execution_in_temp = True
nb_execution_raise_on_error = False
nb_execution_show_tb = True
nb_execution_timeout = 300
nb_merge_streams = True

myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
# Anchors as GitHub makes them, so a link such as model.md#63-power-balance works on GitHub, in
# the rustdoc and here.
myst_heading_anchors = 4
# model.md is plain text on GitHub and in rustdoc; ```math blocks there are displayed equations.
myst_fence_as_directive = ["math"]

html_theme = "furo"
html_title = f"orbitflex {release}"
html_static_path = []
html_last_updated_fmt = None
html_copy_source = False
templates_path = []

# --- MathJax 3 from the site itself (no CDN): the TeX→CommonHTML bundle, its fonts and the TeX
# extensions it loads on demand, about 2 MB, copied from the sphinx-mathjax-offline wheel. -----
def _mathjax_dir() -> Path:
    files = importlib.metadata.files("sphinx-mathjax-offline") or []
    for f in files:
        if str(f).endswith("static/mathjax/tex-chtml.js"):
            return Path(f.locate()).parent
    raise RuntimeError("MathJax not found: pip install 'orbitflex[docs]' (sphinx-mathjax-offline)")


_MATHJAX_OUT = HERE / "_build" / "mathjax_static"
_source = _mathjax_dir()
_target = _MATHJAX_OUT / "mathjax"
if not (_target / "tex-chtml.js").exists():
    for part in ("tex-chtml.js", "output/chtml/fonts/woff-v2", "input/tex/extensions"):
        src, dst = _source / part, _target / part
        dst.parent.mkdir(parents=True, exist_ok=True)
        if src.is_dir():
            shutil.copytree(src, dst, dirs_exist_ok=True)
        else:
            shutil.copy2(src, dst)
html_static_path.append(str(_MATHJAX_OUT))
mathjax_path = "mathjax/tex-chtml.js"

# --- API reference -------------------------------------------------------------------------------
autodoc_member_order = "bysource"
autodoc_typehints = "signature"
autodoc_default_options = {"members": True}
add_module_names = False

# Signatures with types from the stub: the compiled core's docstrings give the text, and pyo3's
# run-time signatures carry no types; _core.pyi (which has no docstrings) has them.
_STUB = Path(orbitflex.__file__).with_name("_core.pyi")
_SIGNATURES = {}
_PROPERTY_TYPES = {}


def _collect(body, prefix):
    for node in body:
        if isinstance(node, ast.ClassDef):
            _collect(node.body, prefix + node.name + ".")
        elif isinstance(node, ast.FunctionDef):
            decorators = {ast.unparse(d) for d in node.decorator_list}
            ret = ast.unparse(node.returns) if node.returns else None
            if "property" in decorators:
                _PROPERTY_TYPES[prefix + node.name] = ret
                continue
            args = node.args
            if args.args and args.args[0].arg in ("self", "cls"):
                args.args = args.args[1:]
            _SIGNATURES.setdefault(prefix + node.name, (f"({ast.unparse(args)})", ret))


_collect(ast.parse(_STUB.read_text()).body, "orbitflex.")


# The stub imports these from orbitflex.analysis; in the signatures of orbitflex's own classes
# they need their full names to link.
_QUALIFY = re.compile(r"\b(Modes|StateSpace)\b")
# The stub's private aliases, spelled out for readers.
_ALIAS_TEXT = {
    "_ArrayLike": "ArrayLike",
    "_Array": "ndarray",
    "_Param": "float | ArrayLike",
    "_Path": "str | PathLike",
    "_Wrench": "ArrayLike | Mapping[str, ArrayLike]",
    "_Controller": "None | ArrayLike | MotorPD | Callable",
}
_ALIASES = re.compile(r"\b(" + "|".join(sorted(_ALIAS_TEXT, key=len, reverse=True)) + r")\b")


def _from_stub(app, what, name, obj, options, signature, return_annotation):
    if what in ("class", "exception"):
        found = _SIGNATURES.get(name + ".__new__")
    elif what in ("function", "method"):
        found = _SIGNATURES.get(name)
    else:
        found = None
    if found is None:
        return None
    args, ret = found
    def readable(text):
        if not text:
            return text
        text = _QUALIFY.sub(r"orbitflex.analysis.\1", text)
        return _ALIASES.sub(lambda m: _ALIAS_TEXT[m.group(0)], text)

    return readable(args), readable(ret)


def _by_suffix(app, env, node, contnode):
    """Resolves a short Python reference such as ``FlexibleArm.modes`` or ``Plan.track``, written
    in a docstring of another module, to the one documented object whose full name ends with it."""
    if node.get("refdomain") != "py":
        return None
    target = node["reftarget"].lstrip("~.")
    domain = env.get_domain("py")
    found = [name for name in domain.objects if name.endswith("." + target)]
    if len(found) != 1:
        return None
    node["reftarget"] = found[0]
    return domain.resolve_xref(env, node["refdoc"], app.builder, node["reftype"], found[0], node, contnode)


def _property_type(app, what, name, obj, options, lines):
    kind = _PROPERTY_TYPES.get(name)
    if what == "property" and kind and not any(line.startswith(":type:") for line in lines):
        lines.extend(["", f":type: {kind}"])


# Names the stub uses in its annotations that are not documented objects of this site.
nitpick_ignore_regex = [
    ("py:class", r"_[A-Za-z]+"),
    ("py:class", r"(np|npt|numpy|numpy\.typing|os|pathlib|typing|collections\.abc)\..*"),
    ("py:class", r"(Sequence|Optional|Mapping|Callable|Any|Union|Dict|List|Tuple|Iterator|Iterable)"),
    ("py:class", r"(Path|PathLike|ArrayLike|NDArray|float64|complex128|ndarray)"),
    ("py:class", r"(pd|pandas)\..*|DataFrame|Client|distributed\..*|dask\..*"),
    ("py:class", r"(array-like|array_like|optional|callable|callable, optional|int, optional|float, optional)"),
    ("py:class", r"(Names|Array|Param|Wrench)"),
    ("py:class", r"meshcat\..*"),
    ("py:obj", r"typing\..*"),
]


def _tagged_equations(app, doctree):
    """A displayed equation with its own ``\\tag{A.n}`` (model.md) goes to MathJax as it is,
    in ``\\[ … \\]``: Sphinx would wrap one with matrix rows (``\\\\``) in ``split``, where a tag
    is not allowed."""
    from docutils import nodes

    for node in doctree.findall(nodes.math_block):
        text = node.astext()
        if "\\tag{" in text and not (node.get("nowrap") or node.get("no-wrap")):
            node["nowrap"] = node["no-wrap"] = True
            node.children = [nodes.Text("\\[" + text + "\\]")]


def setup(app):
    app.connect("doctree-read", _tagged_equations)
    app.connect("autodoc-process-signature", _from_stub)
    app.connect("autodoc-process-docstring", _property_type)
    app.connect("missing-reference", _by_suffix)
