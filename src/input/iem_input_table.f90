!> The table of a namelist group's variables and the checks it drives. Each entry names a
!> variable, its type, where its value is kept once read (a pointer into the configuration),
!> and what is generic about its validation: required or not, a range, allowed words, and
!> the text a message adds (the unit, what it means). From the table come the list of
!> allowed variables, the checks of quoted strings and their lengths, of finite reals and
!> of logical values, and the required/range/allowed checks in the order a reader asks.
module iem_input_table
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use iem_kinds, only: wp
  use iem_constants, only: unset_real, unset_int
  use iem_strings, only: itoa, rtoa, lower
  use iem_namelist_text, only: nml_text_t, line_len
  use iem_input_checks, only: bad, read_error, group_try
  implicit none
  private
  public :: key_t, key, key_only, read_group, check_literals, check_values

  !> Every real input is 0 or of magnitude in [real_min, real_max]: products and quotients of
  !> a few inputs then stay finite and normal in double precision (docs/input.md).
  real(wp), parameter :: real_max = 1.0e30_wp, real_min = 1.0e-30_wp
  integer, parameter :: text_len = 80

  !> One variable of a namelist group.
  type :: key_t
    character(len=32) :: name = ''
    !> 'r' real, 'i' integer, 'l' logical, 's' string (quoted, at most len characters)
    character :: type = 'r'
    integer :: len = 0
    !> The name the value checks use in messages (as the documentation writes it).
    character(len=32) :: shown = ''
    !> check_values refuses the variable unset; the message adds need: 'is required'//need.
    logical :: required = .false.
    character(len=text_len) :: need = ''
    !> '> a', '>= a', '< a', '<= a' or an interval '(a, b]' (any brackets), or ''.
    character(len=16) :: range = ''
    !> Added to a range message: 'must be > 0'//unit.
    character(len=text_len) :: unit = ''
    !> The words a string may hold, blank-separated ('' for any).
    character(len=text_len) :: allowed = ''
    !> Where the value is (one of them associated, or none: nothing to check but the text).
    real(wp), pointer :: r0 => null(), r1(:) => null()
    integer, pointer :: i0 => null()
    logical, pointer :: l0 => null()
    character(len=:), pointer :: s0 => null()
  end type key_t

  !> A table entry for a variable kept in x (its type and size follow from x).
  interface key
    module procedure key_real, key_reals, key_int, key_logical, key_string
  end interface key

contains

  function key_real(name, x, need, range, unit, shown) result(k)
    character(len=*), intent(in) :: name
    real(wp), intent(in), target :: x
    character(len=*), intent(in), optional :: need, range, unit, shown
    type(key_t) :: k
    k = key_only(name, 'r', need=need, range=range, unit=unit, shown=shown)
    k%r0 => x
  end function key_real

  function key_reals(name, x, need) result(k)
    character(len=*), intent(in) :: name
    real(wp), intent(in), target :: x(:)
    character(len=*), intent(in), optional :: need
    type(key_t) :: k
    k = key_only(name, 'r', need=need)
    k%r1 => x
  end function key_reals

  function key_int(name, x, need, range, unit) result(k)
    character(len=*), intent(in) :: name
    integer, intent(in), target :: x
    character(len=*), intent(in), optional :: need, range, unit
    type(key_t) :: k
    k = key_only(name, 'i', need=need, range=range, unit=unit)
    k%i0 => x
  end function key_int

  function key_logical(name, x) result(k)
    character(len=*), intent(in) :: name
    logical, intent(in), target :: x
    type(key_t) :: k
    k = key_only(name, 'l')
    k%l0 => x
  end function key_logical

  function key_string(name, x, need, allowed) result(k)
    character(len=*), intent(in) :: name
    character(len=*), intent(in), target :: x
    character(len=*), intent(in), optional :: need, allowed
    type(key_t) :: k
    k = key_only(name, 's', len(x), need=need, allowed=allowed)
    k%s0 => x
  end function key_string

  !> A table entry of the given type whose value is not kept where the checks can see it:
  !> only its text is checked (string quotes and length len, logical words).
  function key_only(name, type, len, need, range, unit, allowed, shown) result(k)
    character(len=*), intent(in) :: name
    character, intent(in) :: type
    integer, intent(in), optional :: len
    character(len=*), intent(in), optional :: need, range, unit, allowed, shown
    type(key_t) :: k
    k%name = name
    k%type = type
    k%shown = name
    if (present(len)) k%len = len
    if (present(need)) then
      k%required = .true.
      k%need = need
    end if
    if (present(range)) k%range = range
    if (present(unit)) k%unit = unit
    if (present(allowed)) k%allowed = allowed
    if (present(shown)) k%shown = shown
  end function key_only

  !> Open group g (called label in messages) for reading: refuse a variable that keys does
  !> not list, then a text that the namelist read (try) cannot read, naming its line, then
  !> a string value that is not quoted or too long. chunk: the group's text, to read.
  subroutine read_group(text, g, keys, label, try, chunk, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    type(key_t), intent(in) :: keys(:)
    character(len=*), intent(in) :: label
    procedure(group_try) :: try
    character(len=line_len), allocatable, intent(out) :: chunk(:)
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=256) :: iomsg
    call check_keys(text, g, keys, label, stat, msg)
    if (stat /= 0) return
    ! a quoted value too long for its variable before the read (gfortran's runtime, in a
    ! checked build, would warn as it cuts it)
    call check_strings(text, g, keys, label, .true., stat, msg)
    if (stat /= 0) return
    call text%chunk(g, chunk)
    stat = try(chunk, iomsg)
    if (stat /= 0) then
      call read_error(text, g, label, trim(iomsg), chunk, try, msg)
      stat = 1
      return
    end if
    call check_strings(text, g, keys, label, .false., stat, msg)
  end subroutine read_group

  !> Check the variable names of group g against the table.
  subroutine check_keys(text, g, keys, label, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    type(key_t), intent(in) :: keys(:)
    character(len=*), intent(in) :: label
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer :: k, j
    character(len=:), allocatable :: list
    stat = 0
    msg = ''
    associate(grp => text%groups(g))
      do k = 1, grp%n_keys
        if (find(keys, grp%keys(k)) > 0) cycle
        list = trim(keys(1)%name)
        do j = 2, size(keys)
          list = list//', '//trim(keys(j)%name)
        end do
        stat = 1
        msg = label//': unknown variable "'//trim(grp%keys(k))//'" on line '// &
              itoa(grp%key_lines(k))//' (allowed: '//list//')'
        return
      end do
    end associate
  end subroutine check_keys

  !> Refuse a string variable of group g longer than the characters it is kept in (before_read:
  !> before the namelist read, which would cut it), or written without quotes (after the read:
  !> Fortran would take 1.5e3 or a misspelt .true. as a string).
  subroutine check_strings(text, g, keys, label, before_read, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    type(key_t), intent(in) :: keys(:)
    character(len=*), intent(in) :: label
    logical, intent(in) :: before_read
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=:), allocatable :: raw
    integer :: k, j, n
    stat = 0
    msg = ''
    associate(grp => text%groups(g))
      do k = 1, grp%n_keys
        j = find(keys, grp%keys(k))
        if (j == 0) cycle
        if (keys(j)%type /= 's') cycle
        raw = text%raw_value(g, k)
        n = -1
        if (len(raw) >= 2) then
          ! characters inside the quotes, a doubled quote counting once
          if (raw(1:1) == "'" .or. raw(1:1) == '"') n = len(raw) - 2 - &
            count_doubled(raw(2:len(raw) - 1), raw(1:1))
        end if
        if (n < 0 .and. .not. before_read) then
          call bad(label, trim(grp%keys(k)), raw, "must be a quoted string ('...')", stat, msg)
          return
        else if (n > keys(j)%len .and. before_read) then
          call bad(label, trim(grp%keys(k)), raw, 'is longer than '//itoa(keys(j)%len)// &
                   ' characters', stat, msg)
          return
        end if
      end do
    end associate
  end subroutine check_strings

  pure integer function count_doubled(s, q) result(n)
    character(len=*), intent(in) :: s
    character, intent(in) :: q
    integer :: i
    n = 0
    i = 1
    do while (i < len(s))
      if (s(i:i) == q .and. s(i+1:i+1) == q) then
        n = n + 1
        i = i + 2
      else
        i = i + 1
      end if
    end do
  end function count_doubled

  !> Refuse, among the variables group g gives, a real that is NaN, Inf or of a magnitude
  !> outside [real_min, real_max] (in table order), then a logical written as anything but
  !> .true./.false. (or T/F): Fortran would read any word starting with t or f as one.
  subroutine check_literals(text, g, keys, label, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    type(key_t), intent(in) :: keys(:)
    character(len=*), intent(in) :: label
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=*), parameter :: words(*) = [character(len=7) :: '.true.', '.false.', &
      'true', 'false', 't', 'f', '.t.', '.f.', '.t', '.f']
    character(len=:), allocatable :: token
    real(wp), allocatable :: v(:)
    integer :: k, j
    stat = 0
    msg = ''
    associate(grp => text%groups(g))
      do k = 1, size(keys)
        if (findloc(grp%keys(1:grp%n_keys), trim(keys(k)%name), 1) == 0) cycle
        if (associated(keys(k)%r0)) then
          v = [keys(k)%r0]
        else if (associated(keys(k)%r1)) then
          v = keys(k)%r1
        else
          cycle
        end if
        do j = 1, size(v)
          if (.not. ieee_is_finite(v(j))) then
            call bad(label, trim(keys(k)%name), rtoa(v(j)), 'must be a finite number', stat, msg)
          else if (v(j) /= 0.0_wp .and. (abs(v(j)) > real_max .or. abs(v(j)) < real_min)) then
            call bad(label, trim(keys(k)%name), rtoa(v(j)), 'is out of range: a real input '// &
                     'must be 0 or of magnitude between 1e-30 and 1e30', stat, msg)
          end if
          if (stat /= 0) return
        end do
      end do
      do k = 1, grp%n_keys
        j = find(keys, grp%keys(k))
        if (j == 0) cycle
        if (keys(j)%type /= 'l') cycle
        token = lower(text%value(g, k))
        if (findloc(words, token, 1) == 0) then
          call bad(label, trim(grp%keys(k)), token, 'must be .true. or .false.', stat, msg)
          return
        end if
      end do
    end associate
  end subroutine check_literals

  !> Check the variables listed in names (blank-separated, in that order) against what the
  !> table says of them: given when required, within range, one of the allowed words.
  subroutine check_values(keys, names, label, stat, msg)
    type(key_t), intent(in) :: keys(:)
    character(len=*), intent(in) :: names, label
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer :: i, j, k
    character(len=:), allocatable :: shown
    stat = 0
    msg = ''
    i = 1
    do while (stat == 0 .and. i <= len_trim(names))
      j = index(names(i:)//' ', ' ') + i - 1
      k = find(keys, names(i:j - 1))
      if (k == 0) then
        call bad(label, names(i:j - 1), '', 'is not in the table of its group (an internal '// &
                 'error)', stat, msg)
        return
      end if
      i = verify(names(j:)//'x', ' ') + j - 1
      associate(e => keys(k))
        shown = trim(e%shown)
        if (e%required .and. unset(e)) then
          call bad(label, shown, '(not given)', 'is required'//trim(e%need), stat, msg)
        else if (associated(e%r0) .and. len_trim(e%range) > 0) then
          if (.not. in_range(e%r0, e%range)) call bad(label, shown, rtoa(e%r0), &
            'must be '//range_text(e%range)//trim(e%unit), stat, msg)
        else if (associated(e%i0) .and. len_trim(e%range) > 0) then
          if (.not. in_range(real(e%i0, wp), e%range)) call bad(label, shown, itoa(e%i0), &
            'must be '//range_text(e%range)//trim(e%unit), stat, msg)
        else if (associated(e%s0) .and. len_trim(e%allowed) > 0) then
          if (.not. is_word(trim(e%s0), e%allowed)) call bad(label, shown, "'"//trim(e%s0)// &
            "'", 'must be '//word_list(e%allowed), stat, msg)
        end if
      end associate
    end do
  end subroutine check_values

  !> The entry of keys named name (0: none).
  pure integer function find(keys, name) result(k)
    type(key_t), intent(in) :: keys(:)
    character(len=*), intent(in) :: name
    do k = 1, size(keys)
      if (keys(k)%name == name) return
    end do
    k = 0
  end function find

  !> True when the variable of e holds its unset marker (for a string: is blank).
  logical function unset(e)
    type(key_t), intent(in) :: e
    unset = .false.
    if (associated(e%r0)) unset = e%r0 == unset_real
    if (associated(e%r1)) unset = any(e%r1 == unset_real)
    if (associated(e%i0)) unset = e%i0 == unset_int
    if (associated(e%s0)) unset = len_trim(e%s0) == 0
  end function unset

  !> True when x satisfies range ('> a', '>= a', '< a', '<= a' or an interval); a range
  !> the table misspells holds no value, so that the first test of it finds it.
  logical function in_range(x, range) result(ok)
    real(wp), intent(in) :: x
    character(len=*), intent(in) :: range
    real(wp) :: a, b
    integer :: c
    character(len=:), allocatable :: r
    r = trim(adjustl(range))
    select case (r(1:1))
    case ('(', '[')
      c = index(r, ',')
      read(r(2:c - 1), *) a
      read(r(c + 1:len(r) - 1), *) b
      ok = (x > a .or. (r(1:1) == '[' .and. x == a)) .and. &
           (x < b .or. (r(len(r):len(r)) == ']' .and. x == b))
    case default
      c = scan(r, '0123456789-+.')
      read(r(c:), *) a
      select case (r(1:c - 1))
      case ('> ')
        ok = x > a
      case ('>= ')
        ok = x >= a
      case ('< ')
        ok = x < a
      case ('<= ')
        ok = x <= a
      case default
        ok = .false.
      end select
    end select
  end function in_range

  !> How a message writes range: 'in (0, 1]' for an interval, else the range itself.
  function range_text(range) result(t)
    character(len=*), intent(in) :: range
    character(len=:), allocatable :: t
    t = trim(adjustl(range))
    if (t(1:1) == '(' .or. t(1:1) == '[') t = 'in '//t
  end function range_text

  !> True when word is one of the blank-separated words of list.
  pure logical function is_word(word, list)
    character(len=*), intent(in) :: word, list
    is_word = len(word) > 0 .and. index(' '//trim(list)//' ', ' '//word//' ') > 0
  end function is_word

  !> The blank-separated words of list as "'a', 'b' or 'c'".
  function word_list(list) result(t)
    character(len=*), intent(in) :: list
    character(len=:), allocatable :: t, rest
    integer :: j, n
    t = ''
    rest = trim(adjustl(list))
    n = 0
    do while (len(rest) > 0)
      j = index(rest//' ', ' ')
      if (n > 0) then
        if (len_trim(rest(j:)) == 0) then
          t = t//' or '
        else
          t = t//', '
        end if
      end if
      t = t//"'"//rest(1:j - 1)//"'"
      rest = trim(adjustl(rest(j:)))
      n = n + 1
    end do
  end function word_list
end module iem_input_table
