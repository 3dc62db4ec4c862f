#!/usr/bin/env python3
"""pfunit_lite preprocessor: turns a pFUnit 4 .pf file into plain Fortran.

    pfproc.py [--serial] TEST.pf OUT.F90      translate one .pf file
    pfproc.py --driver [--serial] DRIVER.F90 A.pf ...
                                              write the main program that runs them all

--serial: the test target has no MAX_PES, so pFUnit links it with funit only (no `pfunit`
module, no MPI tests) and runs it without mpiexec.

The module of the .pf file is copied line for line (a `#line` marker at the top makes
compiler messages point into the .pf file); each @-directive becomes Fortran on its own
line. After the module comes a generated module `Wrap<module>` with `<module>_suite()`,
which runs the tests in file order; like pFUnit's generated suite function it `use`s the
test module whole, takes MpiTestMethod from it and declares the local variables `t` and
`suite`, so that the compiler rejects what it rejects with pFUnit.

The input must be what pFUnit 4.14's funitproc and generated code accept; what is not is
reported as `file:line: error: ...` (see README.md, "What pFUnit rejects").
"""
import os
import re
import sys

DIRECTIVE = re.compile(r'^(\s*)@(\w+)(.*)$')
MODULE = re.compile(r'^\s*module\s+(\w+)\s*$', re.I)
# funitproc recognises a test or fixture procedure only in exactly this form (one line,
# no prefix such as recursive/impure/module, dummy names only)
SUBROUTINE = re.compile(r'^\s*subroutine\s+(\w+)\s*(?:\(([\w\s,]*)\))?\s*$', re.I)
ASSERTION = re.compile(r'^(mpi)?(assert\w+)$', re.I)
# operands that funitproc requires before it expands an assertion (its assert_operands)
OPERANDS = {'assertequal': 2, 'assertrelativelyequal': 2, 'asserttrue': 1, 'assertfalse': 1,
            'assertlessthan': 2, 'assertlessthanorequal': 2, 'assertgreaterthan': 2,
            'assertgreaterthanorequal': 2}
# names that pFUnit's generated suite function declares or references next to `use <module>`
SUITE_LOCALS = ('t', 'suite')


class PfError(Exception):
    """An error in a .pf file, reported as file:line: message."""


def strip_comment(text):
    """Drops a trailing `!` comment that is not inside a string."""
    quote = None
    for k, c in enumerate(text):
        if quote:
            if c == quote:
                quote = None
        elif c in '"\'':
            quote = c
        elif c == '!':
            return text[:k]
    return text


def outside_strings(text):
    """The code of a line with string contents blanked out (comment dropped)."""
    out, quote = [], None
    for c in strip_comment(text):
        if quote:
            if c == quote:
                quote = None
                out.append(c)
            else:
                out.append(' ')
        else:
            if c in '"\'':
                quote = c
            out.append(c)
    return ''.join(out)


def split_top(args, sep=','):
    """Splits at top-level separators (not inside parentheses, brackets or strings)."""
    pieces, depth, quote, start = [], 0, None, 0
    for k, c in enumerate(args + sep):
        if quote:
            if c == quote:
                quote = None
        elif c in '"\'':
            quote = c
        elif c in '([':
            depth += 1
        elif c in ')]':
            depth -= 1
        elif c == sep and depth == 0:
            pieces.append(args[start:k].strip())
            start = k + 1
    return pieces


def split_parens(text, lineno):
    """Splits '(args) rest' at the matching parenthesis; strings may hold ( ) and ,"""
    text = text.strip()
    if not text.startswith('('):
        raise PfError(lineno, 'expected "(" after the directive')
    depth, quote = 0, None
    for k, c in enumerate(text):
        if quote:
            if c == quote:
                quote = None
        elif c in '"\'':
            quote = c
        elif c == '(':
            depth += 1
        elif c == ')':
            depth -= 1
            if depth == 0:
                return text[1:k].strip(), text[k + 1:].strip()
    raise PfError(lineno, 'unbalanced parentheses')


def wrap_args(args):
    """Puts each argument (or keyword argument's value) in parentheses.

    gfortran 12 passes a garbage descriptor when the result of a type-bound function of a
    polymorphic object, e.g. this%getNumProcesses(), goes straight to a class(*) dummy;
    an expression in parentheses is passed correctly."""
    keyword = re.compile(r'^(\w+)\s*=(?!=)\s*(.*)$', re.S)
    return ', '.join('%s=(%s)' % keyword.match(p).groups() if keyword.match(p) else '(%s)' % p
                     for p in split_top(args))


def next_subroutine(lines, i, directive, lineno):
    """Name and dummy arguments of the subroutine after a @test/@before/@after line."""
    for j in range(i, len(lines)):
        code = strip_comment(lines[j]).strip()
        if not code:
            continue
        m = SUBROUTINE.match(code)
        if not m:
            raise PfError(j + 1, '@%s (line %d) must be followed by a line "subroutine name" or '
                          '"subroutine name(this)": pFUnit recognises no prefix (recursive, '
                          'impure, module ...) and no "&" continuation there' % (directive, lineno))
        dummies = [a.strip() for a in (m.group(2) or '').split(',') if a.strip()]
        return m.group(1), dummies
    raise PfError(lineno, '@%s must be followed by a subroutine' % directive)


def parse_npes(args, lineno):
    """The npes=[...] list of a @test(...) directive, or None."""
    m = re.search(r'npes\s*=\s*\[([^\]]*)\]', args, re.I)
    if not m:
        return None
    if not re.fullmatch(r'[0-9,\s]+', m.group(1)):
        raise PfError(lineno, 'npes must be a list of non-negative integers')
    return [int(n) for n in m.group(1).split(',') if n.strip()]


class ModuleInfo:
    """What the specification part and the procedures of the test module make public."""

    def __init__(self):
        self.default_private = False
        self.public, self.private = set(), set()
        self.entities = {}            # lower-case name -> (line, kind)
        self.uses = set()             # modules used (lower case)

    def is_public(self, name):
        name = name.lower()
        if name in self.public:
            return True
        return not self.default_private and name not in self.private


def scan_module(lines, pf_name):
    """Scans the module (after joining & continuations of ordinary statements)."""
    info = ModuleInfo()
    module, module_line = None, 0
    in_contains, depth, block = False, 0, 0     # depth: procedures after contains
    i = 0
    while i < len(lines):
        start = i
        code = outside_strings(lines[i]).rstrip()
        i += 1
        if DIRECTIVE.match(lines[start]):
            continue
        while code.endswith('&') and i < len(lines):
            nxt = outside_strings(lines[i]).strip()
            i += 1
            if nxt.startswith('&'):
                nxt = nxt[1:]
            code = code[:-1] + ' ' + nxt
            code = code.rstrip()
        lineno = start + 1
        stmt = code.strip()
        low = stmt.lower()
        if not stmt:
            continue
        m = MODULE.match(stmt)
        if m:
            if module is not None:
                raise PfError(lineno, 'a second module (%s) in one .pf file: pFUnit builds its '
                              'suite from one module per file' % m.group(1))
            module, module_line = m.group(1), lineno
            continue
        if module is None:
            continue
        if re.match(r'end\s*module\b', low):
            break
        if not in_contains:
            if re.match(r'(type|interface|abstract\s+interface)\b(?!\s*\()', low) and \
                    not re.match(r'type\s*\(', low):
                tm = re.match(r'type\s*(?:,[^:]*)?(?:::)?\s*(\w+)\s*$', low)
                if tm and block == 0 and tm.group(1) not in ('is',):
                    info.entities.setdefault(tm.group(1), (lineno, 'derived type'))
                block += 1
                continue
            if re.match(r'end\s*(type|interface)\b', low):
                block -= 1
                continue
            if block:
                continue
            if low == 'contains':
                in_contains = True
                continue
            if low == 'private':
                info.default_private = True
                continue
            am = re.match(r'(public|private)\s*(?:::)?\s*(\w.*)$', low)
            if am:
                names = {n.strip() for n in am.group(2).split(',')}
                (info.public if am.group(1) == 'public' else info.private).update(names)
                continue
            um = re.match(r'use\b\s*(?:,\s*(?:non_)?intrinsic\s*)?(?:::)?\s*(\w+)\s*(.*)$', low)
            if um:
                info.uses.add(um.group(1))
                om = re.match(r',\s*only\s*:(.*)$', um.group(2))
                if om:
                    for item in om.group(1).split(','):
                        local = item.split('=>')[0].strip()
                        if re.fullmatch(r'\w+', local):
                            info.entities.setdefault(local, (lineno, 'use-associated name'))
                continue
            if '::' in stmt:
                for piece in split_top(stmt.split('::', 1)[1]):
                    nm = re.match(r'\s*(\w+)', piece)
                    if nm:
                        info.entities.setdefault(nm.group(1).lower(), (lineno, 'module variable'))
        else:
            pm = re.match(r'(?:(?:pure|elemental|impure|recursive|module|non_recursive)\s+|'
                          r'(?:\w+(?:\s*\([^)]*\))?\s+))*(subroutine|function)\s+(\w+)', low)
            if pm and not low.startswith('end'):
                if depth == 0:
                    info.entities.setdefault(pm.group(2), (lineno, 'module procedure'))
                depth += 1
            elif re.match(r'end\s*(subroutine|function)\b', low) or \
                    (low == 'end' and depth > 0):
                depth -= 1
    if module is None:
        raise PfError(1, 'no module found')
    return module, module_line, info


def translate(pf_path, out_path, serial=False):
    """Writes the Fortran for one .pf file; returns its module name."""
    with open(pf_path) as f:
        lines = f.read().splitlines()
    pf_name = os.path.basename(pf_path)
    module, module_line, info = scan_module(lines, pf_name)
    stem = pf_name.split('.')[0]
    if module.lower() != stem.lower():
        raise PfError(module_line, 'module %s must be named like its file, %s (pFUnit\'s driver '
                      'calls %s_suite)' % (module, stem, stem))
    out = ['#line 1 "%s"' % os.path.abspath(pf_path)]
    tests, fixtures = [], {}
    i = 0
    while i < len(lines):
        m = DIRECTIVE.match(lines[i])
        if not m:
            code = outside_strings(lines[i])
            if '@' in code:
                raise PfError(i + 1, 'an @-directive must start its line (pFUnit leaves this '
                              'line unchanged and the compiler rejects the "@")')
            out.append(lines[i])
            i += 1
            continue
        lineno = i + 1
        indent, word = m.group(1), m.group(2)
        text = strip_comment(lines[i]).rstrip()
        if text != lines[i].rstrip():
            raise PfError(lineno, 'a comment after @%s: pFUnit reads a directive only when '
                          'its line ends with it; put the comment on its own line' % word)
        if text.endswith('&'):
            raise PfError(lineno, '@%s is continued with "&": pFUnit reads a directive only '
                          'when it stands on one line (put long arguments into variables '
                          'first)' % word)
        i += 1
        rest = text.lstrip()[1 + len(word):]
        key = word.lower()
        if key in ('test', 'mpitest'):
            args = ''
            if rest.strip():
                args, tail = split_parens(rest, lineno)
                if tail:
                    raise PfError(lineno, 'unexpected text after @%s(...): %s' % (word, tail))
            name, dummies = next_subroutine(lines, i, word, lineno)
            npes = parse_npes(args, lineno)
            if npes is None and dummies:
                raise PfError(lineno, '@%s without npes=[...] is a serial test in pFUnit, whose '
                              'subroutine %s must take no argument (for an MPI test write '
                              '@test(npes=[1]))' % (word, name))
            if npes is not None and len(dummies) != 1:
                raise PfError(lineno, '@%s(npes=...) is an MPI test: its subroutine %s must take '
                              'one argument, class(MpiTestMethod), intent(inout)' % (word, name))
            if npes is not None and serial:
                raise PfError(lineno, 'an MPI test in a test target without MAX_PES: pFUnit '
                              'links that target with funit only and runs it without mpiexec')
            tests.append((name, npes, lineno))
            code = '! @%s' % text.strip()[1:]
        elif key in ('before', 'after'):
            if rest.strip():
                raise PfError(lineno, '@%s takes no arguments in pFUnit' % word)
            name, dummies = next_subroutine(lines, i, word, lineno)
            fixtures[key] = (name, dummies, lineno)
            code = '! @%s' % key
        elif ASSERTION.match(word) and ASSERTION.match(word).group(2).lower() in OPERANDS:
            args, tail = split_parens(rest, lineno)
            if tail:
                raise PfError(lineno, 'unexpected text after @%s(...): %s' % (word, tail))
            mpi, call = ASSERTION.match(word).groups()
            need = OPERANDS[call.lower()]
            if len([a for a in split_top(args) if a]) < need:
                raise PfError(lineno, '@%s needs at least %d argument%s' % (
                    word, need, 's' if need > 1 else ''))
            where = "location=SourceLocation('%s', %d)" % (pf_name, lineno)
            code = 'call %s(%s, %s)' % (call, wrap_args(args), where)
            if not mpi:
                # pFUnit 4.14 returns after a failed @assert; after a failed @mpiAssert the
                # test goes on (its funitproc writes no return there)
                code += '; if (anyExceptions()) return'
        else:
            raise PfError(lineno, 'pfunit_lite does not support @%s' % word)
        out.append(indent + code)
    check_module(module, info, tests, fixtures, serial, pf_name)
    out.append('#line %d "%s"' % (len(out) + 2, os.path.abspath(out_path)))
    out.extend(suite_module(module, tests, fixtures))
    with open(out_path, 'w') as f:
        f.write('\n'.join(out) + '\n')
    return module


def check_module(module, info, tests, fixtures, serial, pf_name):
    """The rules that pFUnit's generated suite function and constructors impose."""
    if serial and 'pfunit' in info.uses:
        raise PfError(1, '"use pfunit" in a test target without MAX_PES: pFUnit links that '
                      'target with funit only (use funit, or give the target MAX_PES)')
    for name in SUITE_LOCALS + ('%s_suite' % module.lower(),):
        if name in info.entities and info.is_public(name):
            line, kind = info.entities[name]
            raise PfError(line, 'public %s "%s" clashes with the "%s" of pFUnit\'s generated '
                          'suite function, which uses this module whole: rename it or make it '
                          'private' % (kind, name, name))
    mpi_tests = [t for t in tests if t[1] is not None]
    serial_tests = [t for t in tests if t[1] is None]
    if mpi_tests and not info.is_public('mpitestmethod'):
        raise PfError(mpi_tests[0][2], 'the module is private: pFUnit\'s generated suite function '
                      'sees MpiTestMethod only through it; add "public :: MpiTestMethod"')
    for name, _, lineno in tests:
        if not info.is_public(name):
            raise PfError(lineno, 'test %s is private: pFUnit\'s generated suite function '
                          'cannot call it; make it public' % name)
    for key, (name, dummies, lineno) in fixtures.items():
        if not info.is_public(name):
            raise PfError(lineno, '@%s %s is private: make it public' % (key, name))
        if mpi_tests and len(dummies) != 1:
            raise PfError(lineno, '@%s %s must take one argument, class(MpiTestMethod), '
                          'intent(inout), because the module has MPI tests' % (key, name))
        if serial_tests and dummies:
            raise PfError(lineno, '@%s %s takes an argument, but test %s is serial: pFUnit '
                          'passes the same fixture to every test of the module'
                          % (key, name, serial_tests[0][0]))
    if mpi_tests and len(fixtures) == 1:
        key, (name, _, lineno) = next(iter(fixtures.items()))
        raise PfError(lineno, '@%s without @%s: pFUnit\'s MpiTestMethod takes @before and @after '
                      'together or neither' % (key, 'after' if key == 'before' else 'before'))


def suite_module(module, tests, fixtures):
    """The generated module with the suite routine (the shape of pFUnit's suite function)."""
    mpi = any(test[1] is not None for test in tests)
    body = ['module Wrap%s' % module,
            '  implicit none',
            '  private',
            '  public :: %s_suite' % module,
            'contains',
            '  !> Runs the tests of module %s in file order.' % module,
            '  subroutine %s_suite()' % module,
            # as in pFUnit's suite function: the test module is used whole here, so a public
            # t or suite in it clashes with these locals, and MpiTestMethod must come from it
            '    use %s' % module,
            '    use funit, only: pfl_run_serial',
            *(['    use pfunit, only: pfl_run_mpi'] if mpi else []),
            '    integer :: suite',
            '    %s, allocatable :: t' % ('class(MpiTestMethod)' if mpi else 'integer'),
            '    suite = 0',
            '    if (allocated(t)) suite = 1']
    fix = ''
    if 'before' in fixtures:
        fix += ', setUp=%s' % fixtures['before'][0]
    if 'after' in fixtures:
        fix += ', tearDown=%s' % fixtures['after'][0]
    for name, npes, _ in tests:
        if npes is None:
            body.append("    call pfl_run_serial('%s', %s%s)" % (name, name, fix))
        else:
            body.append("    call pfl_run_mpi('%s', [integer :: %s], %s%s)"
                        % (name, ', '.join(map(str, npes)), name, fix))
    body.append('  end subroutine %s_suite' % module)
    body.append('end module Wrap%s' % module)
    return body


def module_name(pf_path):
    """The module name declared in a .pf file."""
    with open(pf_path) as f:
        for line in f:
            m = MODULE.match(strip_comment(line))
            if m:
                return m.group(1)
    raise PfError(1, 'no module found')


def write_driver(out_path, pf_paths, modules, serial):
    """Writes the main program that runs the suites of all the .pf files in order."""
    text = ['! Generated by pfunit_lite/pfproc.py: runs the tests of',
            *['!   %s' % os.path.basename(p) for p in pf_paths],
            'program pfunit_lite_driver',
            '  use funit, only: pfl_init, pfl_finalize',
            *['  use Wrap%s, only: %s_suite' % (m, m) for m in modules],
            '  implicit none',
            '  logical :: ok',
            '  call pfl_init(use_mpi=%s)' % ('.false.' if serial else '.true.'),
            *['  call %s_suite()' % m for m in modules],
            '  call pfl_finalize(ok)',
            '  if (.not. ok) error stop 1',
            '  stop',
            'end program pfunit_lite_driver']
    with open(out_path, 'w') as f:
        f.write('\n'.join(text) + '\n')


def main(argv):
    driver = bool(argv) and argv[0] == '--driver'
    if driver:
        argv = argv[1:]
    serial = bool(argv) and argv[0] == '--serial'
    if serial:
        argv = argv[1:]
    if (driver and len(argv) < 2) or (not driver and len(argv) != 2):
        sys.exit(__doc__)
    current = None
    try:
        if driver:
            modules = []
            for current in argv[1:]:
                modules.append(module_name(current))
            write_driver(argv[0], argv[1:], modules, serial)
        else:
            current = argv[0]
            translate(argv[0], argv[1], serial)
    except PfError as err:
        sys.exit('%s:%d: error: %s' % (current, err.args[0], err.args[1]))
    except OSError as err:
        sys.exit('pfproc.py: %s' % err)


if __name__ == '__main__':
    main(sys.argv[1:])
