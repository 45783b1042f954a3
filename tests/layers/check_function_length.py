#!/usr/bin/env python3
"""No function over about 80 lines: lists the function bodies of the project's own code that are longer.

  check_function_length.py [--limit N] [SOURCE_DIR]

SOURCE_DIR (default: the tree this script is in): every .cpp, .hpp and .h file of dsp, model, drivers, daemon, cli and
their subfolders (tests are not checked). A function's length is the lines of its body, from the line of its
opening brace to the line of its closing brace; a lambda or a local class inside a function counts toward the
enclosing function, while the bodies of namespaces, classes, structs, unions and enums are scopes, not functions
(their member functions are measured one by one). Comments, string and character literals (raw strings too),
preprocessor lines and initializer braces are no function. Exit 0 when no body is over N lines (default 80), 1
with one line per function that is ("path:line: name: L lines"), 2 on a usage error.
"""
import os
import re
import sys

FOLDERS = ["dsp", "model", "drivers", "daemon", "cli"]
EXTENSIONS = (".cpp", ".hpp", ".h")
DEFAULT_LIMIT = 80

STRING_PREFIXES = {"", "u8", "u", "U", "L"}
TYPE_KEYWORDS = {"class", "struct", "union", "enum", "namespace"}
# Parentheses after these do not open a parameter list.
NOT_A_PARAMETER_LIST = {"decltype", "alignas", "noexcept", "sizeof", "alignof", "requires", "__attribute__",
                        "static_assert", "throw"}
# What may stand between a parameter list's ")" and a function body.
QUALIFIERS = {"const", "volatile", "noexcept", "override", "final", "mutable", "constexpr", "consteval", "&", "&&",
              "try"}
ACCESS = {"public", "private", "protected"}


def blank_literals(text):
    """The text with comments, string and character literals and preprocessor lines blanked (newlines kept, so
    line numbers stay); each string literal leaves "" behind so `extern "C"` still reads as a linkage."""
    out = []
    i, n = 0, len(text)
    line_start = True  # only blanks since the last newline
    while i < n:
        c = text[i]
        if c == "\n":
            out.append(c)
            i += 1
            line_start = True
            continue
        if line_start and c == "#":  # a preprocessor line, with its backslash continuations
            while i < n and text[i] != "\n":
                if text[i] == "\\" and i + 1 < n and text[i + 1] == "\n":
                    out.append("\n")
                    i += 2
                    continue
                i += 1
            continue
        if c in " \t\r\f\v":
            out.append(c)
            i += 1
            continue
        line_start = False
        if text.startswith("//", i):
            while i < n and text[i] != "\n":
                i += 1
            continue
        if text.startswith("/*", i):
            end = text.find("*/", i + 2)
            end = n if end < 0 else end + 2
            out.append(re.sub(r"[^\n]", " ", text[i:end]))
            i = end
            continue
        if c.isalpha() or c == "_":
            j = i
            while j < n and (text[j].isalnum() or text[j] == "_"):
                j += 1
            word = text[i:j]
            if j < n and text[j] == '"' and word.endswith("R") and word[:-1] in STRING_PREFIXES:
                i = skip_raw_string(text, j, out)
                continue
            if j < n and text[j] in "\"'" and word in STRING_PREFIXES:
                out.append(" " * len(word))
                i = skip_quoted(text, j, out)
                continue
            out.append(word)
            i = j
            continue
        if c.isdigit() or (c == "." and i + 1 < n and text[i + 1].isdigit()):
            # A number, with its digit separators (1'000) and exponent signs (1e-5, 0x1.0p-53).
            j = i + 1
            while j < n and (text[j].isalnum() or text[j] in "_.'" or (text[j] in "+-" and text[j - 1] in "eEpP")):
                j += 1
            out.append(text[i:j])
            i = j
            continue
        if c in "\"'":
            i = skip_quoted(text, i, out)
            continue
        out.append(c)
        i += 1
    return "".join(out)


def skip_quoted(text, i, out):
    """Skips the "..." or '...' literal starting at i; appends its stand-in; returns the index after it."""
    quote, j, n = text[i], i + 1, len(text)
    while j < n and text[j] != quote and text[j] != "\n":
        j += 2 if text[j] == "\\" else 1
    if j < n and text[j] == quote:
        j += 1
    newlines = text.count("\n", i, j)  # escaped newlines (an unterminated literal ends before its line's end)
    out.append((quote * 2 if quote == '"' else "' '") + "\n" * newlines)
    return j


def skip_raw_string(text, i, out):
    """Skips the raw string R"delim(...)delim" whose quote is at i; returns the index after it."""
    open_paren = text.find("(", i)
    delimiter = text[i + 1:open_paren] if open_paren >= 0 else ""
    end = text.find(")" + delimiter + '"', max(open_paren, i))
    end = len(text) if open_paren < 0 or end < 0 else end + len(delimiter) + 2
    out.append('""' + "\n" * text.count("\n", i, end))
    return end


TOKEN = re.compile(r"\n|::|->|&&|\|\||[A-Za-z_]\w*|\d[\w.']*|\"\"|' '|\S")


def tokens(code):
    """(token, line) pairs of blanked code."""
    line = 1
    for m in TOKEN.finditer(code):
        if m.group() == "\n":
            line += 1
        else:
            yield m.group(), line


def strip_leading(header):
    """The header without leading access labels, attributes and template parameter lists."""
    h = list(header)
    while True:
        if len(h) >= 2 and h[0] in ACCESS and h[1] == ":":
            h = h[2:]
        elif len(h) >= 2 and h[0] == "[" and h[1] == "[":
            depth, k = 0, 0
            while k < len(h):
                depth += {"[": 1, "]": -1}.get(h[k], 0)
                k += 1
                if depth == 0:
                    break
            h = h[k:]
        elif h and h[0] in ("template", "export") and len(h) >= 2 and h[1] == "<":
            depth, k = 0, 1
            while k < len(h):
                if h[k] in "([":
                    depth += 100  # a parenthesised expression: its < and > are no brackets
                elif h[k] in ")]":
                    depth -= 100
                elif h[k] == "<":
                    depth += 1
                elif h[k] == ">":
                    depth -= 1
                k += 1
                if depth == 0:
                    break
            h = h[k:]
        elif h and h[0] in ("export", "inline", "static", "extern") and len(h) >= 2 and h[1] in TYPE_KEYWORDS:
            h = h[1:]
        else:
            return h


def parameter_list(header):
    """Indices (open, close) of the parameter list's parentheses in a header, or None."""
    depth, k = 0, 0
    while k < len(header):
        t = header[k]
        if t == "(" and depth == 0:
            before = header[k - 1] if k > 0 else ""
            close = matching(header, k)
            if close is None:
                return None
            if before == "operator":  # operator()(...): the second pair is the list
                k = close + 1
                continue
            if before not in NOT_A_PARAMETER_LIST:
                return k, close
            k = close + 1
            continue
        if t in "([":
            depth += 1
        elif t in ")]":
            depth -= 1
        k += 1
    return None


def matching(seq, k):
    depth = 0
    for j in range(k, len(seq)):
        depth += {"(": 1, ")": -1}.get(seq[j], 0)
        if depth == 0:
            return j
    return None


def lambda_at_scope(header):
    """A lambda introducer right after "=" at the top level (a namespace-scope lambda: its body is a function)."""
    return any(header[k] == "[" and k > 0 and header[k - 1] == "=" for k in range(len(header)))


def classify(header):
    """What a "{" at namespace or class scope opens, from the tokens before it: "scope" (namespace, class, struct,
    union, enum, extern "C"), "function", "member_init" (a brace in a constructor's initializer list: the header
    goes on after it) or "init" (an initializer)."""
    h = strip_leading(header)
    if not h or h[0] == "using":
        return "init"
    if h[0] in TYPE_KEYWORDS or h[0] == "typedef" or (h[0] == "extern" and h[1:2] == ['""']):
        return "init" if "=" in h else "scope"  # struct S s = {...}: an initializer
    if lambda_at_scope(h):
        return "function"
    plist = parameter_list(h)
    if plist is None:
        return "init"
    tail = h[plist[1] + 1:]
    k = 0
    while k < len(tail) and tail[k] in QUALIFIERS:
        k += 1
        if k < len(tail) and tail[k - 1] == "noexcept" and tail[k] == "(":
            k = (matching(tail, k) or len(tail) - 1) + 1
    rest = tail[k:]
    if not rest:
        return "function"
    if rest[0] in ("->", "requires"):
        return "function"
    if rest[0] == ":":  # a constructor's initializer list: a brace after a member name initialises the member
        return "member_init" if re.fullmatch(r"[A-Za-z_]\w*|>", rest[-1]) else "function"
    return "init"


def function_name(header):
    """The (qualified) name a function header defines; a namespace-scope lambda by the name it is assigned to."""
    h = strip_leading(header)
    if lambda_at_scope(h):
        k = h.index("=")
        return (h[k - 1] if k > 0 else "?") + " (lambda)"
    plist = parameter_list(h)
    if plist is None:
        return "?"
    end = plist[0]
    start = next((end - back for back in range(1, 5) if end - back >= 0 and h[end - back] == "operator"), end - 1)
    if start < 0 or not (h[start] == "operator" or re.fullmatch(r"[A-Za-z_]\w*", h[start])):
        return "?"
    while start >= 1 and h[start - 1] == "~":
        start -= 1
    while start >= 2 and h[start - 1] == "::" and re.fullmatch(r"[A-Za-z_]\w*", h[start - 2]):
        start -= 2
    return "".join(h[start:end])


def long_functions(path, limit):
    """(line, name, length) of each function body in a file that is over `limit` lines."""
    with open(path, encoding="utf-8", errors="replace") as f:
        code = blank_literals(f.read())
    found = []
    stack = []   # one (kind, line, function name) per open brace
    header = []  # tokens since the last ";", "{" or "}" at namespace or class scope
    paren = 0    # parenthesis depth within the header
    for tok, line in tokens(code):
        in_code = any(e[0] in ("function", "block") for e in stack)
        in_init = bool(stack) and stack[-1][0] in ("init", "member_init")
        if tok == "{":
            if in_code:
                stack.append(("block", line, None))
            elif in_init or paren > 0:
                stack.append(("init", line, None))
            else:
                kind = classify(header)
                stack.append((kind, line, function_name(header) if kind == "function" else None))
                if kind in ("scope", "function"):
                    header, paren = [], 0
        elif tok == "}":
            if not stack:
                continue
            kind, start, name = stack.pop()
            if kind == "function":
                if line - start + 1 > limit:
                    found.append((start, name, line - start + 1))
                header, paren = [], 0
            elif kind == "scope":
                header, paren = [], 0
            elif not any(e[0] in ("function", "block", "init", "member_init") for e in stack):
                header.append("}")
        elif in_code or in_init:
            continue
        elif tok == ";" and paren == 0:
            header = []
        else:
            paren += {"(": 1, ")": -1}.get(tok, 0)
            header.append(tok)
    return found


def source_files(root):
    for folder in FOLDERS:
        top = os.path.join(root, folder)
        for directory, subdirs, names in os.walk(top):
            subdirs.sort()
            for name in sorted(names):
                if name.endswith(EXTENSIONS):
                    yield os.path.join(directory, name)


def main(argv):
    args = argv[1:]
    limit = DEFAULT_LIMIT
    if args and args[0] in ("-h", "--help"):
        print(__doc__)
        return 0
    if len(args) >= 2 and args[0] == "--limit":
        if not args[1].isdigit() or int(args[1]) < 1:
            print("--limit: expected a positive number of lines", file=sys.stderr)
            return 2
        limit = int(args[1])
        args = args[2:]
    elif args and args[0].startswith("--limit="):
        value = args[0].split("=", 1)[1]
        if not value.isdigit() or int(value) < 1:
            print("--limit: expected a positive number of lines", file=sys.stderr)
            return 2
        limit = int(value)
        args = args[1:]
    if len(args) > 1 or (args and args[0].startswith("-")):
        print(__doc__, file=sys.stderr)
        return 2
    root = args[0] if args else os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "../.."))
    if not any(os.path.isdir(os.path.join(root, folder)) for folder in FOLDERS):
        print(f"{root}: none of {', '.join(FOLDERS)} is there", file=sys.stderr)
        return 2
    problems = []
    for path in source_files(root):
        for line, name, length in long_functions(path, limit):
            problems.append(f"{os.path.relpath(path, root)}:{line}: {name}: {length} lines (limit {limit})")
    for p in problems:
        print(p)
    if problems:
        print(f"{len(problems)} function(s) over {limit} lines")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
