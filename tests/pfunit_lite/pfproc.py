#!/usr/bin/env python3
"""pfunit_lite preprocessor: turns a pFUnit 4 .pf file into plain Fortran.

    pfproc.py TEST.pf OUT.F90                 translate one .pf file
    pfproc.py --driver DRIVER.F90 A.pf ...    write the main program that runs them all

The module of the .pf file is copied line for line (a `#line` marker at the top makes
compiler messages point into the .pf file); each @-directive becomes Fortran on its own
first line and the lines it continued onto become blank. After the module comes a
generated module `<module>_pfl` with one wrapper per test and `<module>_pfl_suite()`,
which runs the tests in file order. See README.md for the supported syntax.
"""
import os
import re
import sys

DIRECTIVE = re.compile(r'^(\s*)@(\w+)(.*)$')
MODULE = re.compile(r'^\s*module\s+(\w+)\s*$', re.I)
SUBROUTINE = re.compile(
    r'^\s*(?:(?:recursive|impure|module)\s+)*subroutine\s+(\w+)\s*(?:\((.*)\))?\s*$', re.I)
ASSERTION = re.compile(r'^(mpi)?(assert\w+)$', re.I)


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


def join_continued(lines, i):
    """The statement starting at lines[i], with its & continuations; and the next index."""
    text = strip_comment(lines[i]).rstrip()
    i += 1
    while text.endswith('&'):
        if i >= len(lines):
            raise PfError(i, 'continuation line missing at end of file')
        nxt = strip_comment(lines[i]).strip()
        i += 1
        if not nxt:                     # blank and comment lines may sit between them
            continue
        text = text[:-1] + (nxt[1:] if nxt.startswith('&') else nxt)
        text = text.rstrip()
    return text, i


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
    pieces, depth, quote, start = [], 0, None, 0
    for k, c in enumerate(args + ','):
        if quote:
            if c == quote:
                quote = None
        elif c in '"\'':
            quote = c
        elif c in '([':
            depth += 1
        elif c in ')]':
            depth -= 1
        elif c == ',' and depth == 0:
            pieces.append(args[start:k].strip())
            start = k + 1
    keyword = re.compile(r'^(\w+)\s*=(?!=)\s*(.*)$', re.S)
    return ', '.join('%s=(%s)' % keyword.match(p).groups() if keyword.match(p) else '(%s)' % p
                     for p in pieces)


def next_subroutine(lines, i, directive):
    """Name of the subroutine after a @test/@before/@after line, and whether it has arguments."""
    for j in range(i, len(lines)):
        code = strip_comment(lines[j]).strip()
        if not code:
            continue
        m = SUBROUTINE.match(code)
        if not m:
            break
        return m.group(1), bool((m.group(2) or '').strip())
    raise PfError(i, '@%s must be followed by a subroutine' % directive)


def parse_npes(args, lineno):
    """The npes=[...] list of a @test(...) directive, or None."""
    m = re.search(r'npes\s*=\s*\[([^\]]*)\]', args, re.I)
    if not m:
        return None
    try:
        return [int(n) for n in m.group(1).split(',')]
    except ValueError:
        raise PfError(lineno, 'npes must be a list of integers') from None


def translate(pf_path, out_path):
    """Writes the Fortran for one .pf file; returns its module name."""
    with open(pf_path) as f:
        lines = f.read().splitlines()
    pf_name = os.path.basename(pf_path)
    out = ['#line 1 "%s"' % os.path.abspath(pf_path)]
    module, tests, fixtures = None, [], {}
    i = 0
    while i < len(lines):
        m = DIRECTIVE.match(lines[i])
        if not m:
            mod = MODULE.match(strip_comment(lines[i]))
            if mod and module is None:
                module = mod.group(1)
            out.append(lines[i])
            i += 1
            continue
        lineno = i + 1
        indent, word = m.group(1), m.group(2)
        text, i = join_continued(lines, lineno - 1)
        rest = text.lstrip()[1 + len(word):]
        key = word.lower()
        if key in ('test', 'mpitest'):
            args = split_parens(rest, lineno)[0] if rest.strip() else ''
            name, has_arg = next_subroutine(lines, i, word)
            npes = parse_npes(args, lineno)
            if npes is None and (has_arg or key == 'mpitest'):
                npes = [1]
            tests.append((name, npes, has_arg, lineno))
            code = '! @%s' % text.strip()[1:]
        elif key in ('before', 'after'):
            fixtures[key] = next_subroutine(lines, i, word)
            code = '! @%s' % key
        elif ASSERTION.match(word):
            args, tail = split_parens(rest, lineno)
            if tail:
                raise PfError(lineno, 'unexpected text after @%s(...): %s' % (word, tail))
            mpi, call = ASSERTION.match(word).groups()
            where = "location=SourceLocation('%s', %d)" % (pf_name, lineno)
            check = 'anyExceptions(this%getMpiCommunicator())' if mpi else 'anyExceptions()'
            code = 'call %s(%s, %s); if (%s) return' % (call, wrap_args(args), where, check)
        else:
            raise PfError(lineno, 'pfunit_lite does not support @%s' % word)
        out.append(indent + code)
        out.extend([''] * (i - lineno))          # keep the .pf line numbers
    if module is None:
        raise PfError(1, 'no module found')
    out.append('#line %d "%s"' % (len(out) + 2, os.path.abspath(out_path)))
    out.extend(suite_module(module, tests, fixtures))
    with open(out_path, 'w') as f:
        f.write('\n'.join(out) + '\n')
    return module


def suite_module(module, tests, fixtures):
    """The generated module with one wrapper per test and the suite routine."""
    uses = ['pfl_run_serial', 'anyExceptions']
    if any(test[1] is not None for test in tests):
        uses = ['MpiTestMethod', 'pfl_run_mpi'] + uses
    body = ['module %s_pfl' % module,
            '  use %s' % module,
            '  use pfunit, only: %s' % ', '.join(uses),
            '  implicit none',
            '  private',
            '  public :: %s_pfl_suite' % module,
            'contains',
            '  !> Runs the tests of module %s in file order.' % module,
            '  subroutine %s_pfl_suite()' % module]
    for k, (name, npes, _, _) in enumerate(tests, 1):
        if npes is None:
            body.append("    call pfl_run_serial('%s', pfl_w%d)" % (name, k))
        else:
            body.append("    call pfl_run_mpi('%s', [%s], pfl_w%d)"
                        % (name, ', '.join(map(str, npes)), k))
    body.append('  end subroutine %s_pfl_suite' % module)
    for k, (name, npes, has_arg, lineno) in enumerate(tests, 1):
        mpi = npes is not None
        this = '(this)' if mpi else '()'
        body.append('  subroutine pfl_w%d%s' % (k, this))
        if mpi:
            body.append('    class(MpiTestMethod), intent(inout) :: this')
        before, after = fixtures.get('before'), fixtures.get('after')
        for fix in (before, after):
            if fix and fix[1] and not mpi:
                raise PfError(lineno, 'fixture %s takes an argument but %s is serial'
                              % (fix[0], name))
        fix_call = lambda fix: '    call %s%s' % (fix[0], '(this)' if fix[1] else '()')
        check = 'anyExceptions(this%getMpiCommunicator())' if mpi else 'anyExceptions()'
        test_call = 'call %s%s' % (name, '(this)' if has_arg else '()')
        if before:
            body.append(fix_call(before))
            body.append('    if (.not. %s) %s' % (check, test_call))
        else:
            body.append('    ' + test_call)
        if after:
            body.append(fix_call(after))
        body.append('  end subroutine pfl_w%d' % k)
    body.append('end module %s_pfl' % module)
    return body


def module_name(pf_path):
    """The module name declared in a .pf file."""
    with open(pf_path) as f:
        for line in f:
            m = MODULE.match(strip_comment(line))
            if m:
                return m.group(1)
    raise PfError(1, 'no module found')


def write_driver(out_path, pf_paths, modules):
    """Writes the main program that runs the suites of all the .pf files in order."""
    text = ['! Generated by pfunit_lite/pfproc.py: runs the tests of',
            *['!   %s' % os.path.basename(p) for p in pf_paths],
            'program pfunit_lite_driver',
            '  use pfunit, only: pfl_init, pfl_finalize',
            *['  use %s_pfl, only: %s_pfl_suite' % (m, m) for m in modules],
            '  implicit none',
            '  logical :: ok',
            '  call pfl_init()',
            *['  call %s_pfl_suite()' % m for m in modules],
            '  call pfl_finalize(ok)',
            '  if (.not. ok) error stop 1',
            '  stop',
            'end program pfunit_lite_driver']
    with open(out_path, 'w') as f:
        f.write('\n'.join(text) + '\n')


def main(argv):
    driver = len(argv) >= 3 and argv[0] == '--driver'
    if not driver and len(argv) != 2:
        sys.exit(__doc__)
    current = None
    try:
        if driver:
            modules = []
            for current in argv[2:]:
                modules.append(module_name(current))
            write_driver(argv[1], argv[2:], modules)
        else:
            current = argv[0]
            translate(argv[0], argv[1])
    except PfError as err:
        sys.exit('%s:%d: error: %s' % (current, err.args[0], err.args[1]))
    except OSError as err:
        sys.exit('pfproc.py: %s' % err)


if __name__ == '__main__':
    main(sys.argv[1:])
