!> The input file as text: read on rank 0, broadcast, split into namelist groups with the
!> variables each group assigns, so that errors can name the group, variable and line.
module iem_namelist_text
  use mpi_f08, only: MPI_Comm, MPI_Bcast, MPI_INTEGER, MPI_CHARACTER, MPI_Comm_rank
  use iem_strings, only: itoa
  use iem_paths, only: why_not_readable
  implicit none
  private
  public :: nml_text_t, nml_group_t, line_len, key_len

  integer, parameter :: line_len = 512, key_len = 32

  !> One namelist group as it stands in the file.
  type :: nml_group_t
    character(len=key_len) :: name = ''
    integer :: first_line = 0, first_col = 0, last_line = 0, last_col = 0
    integer :: n_keys = 0
    character(len=key_len), allocatable :: keys(:)
    !> The subscript written after each key ('(1)' for box(1) = ...; '' for the whole array).
    character(len=key_len), allocatable :: subs(:)
    integer, allocatable :: key_lines(:)
    !> Column of the '=' of each assignment on its line.
    integer, allocatable :: key_cols(:)
  end type nml_group_t

  !> The whole input file and its groups.
  type :: nml_text_t
    character(len=:), allocatable :: path
    integer :: n_lines = 0
    character(len=line_len), allocatable :: lines(:)
    integer :: n_groups = 0
    type(nml_group_t), allocatable :: groups(:)
  contains
    procedure :: load => nml_text_load
    procedure :: scan => nml_text_scan
    procedure :: chunk => nml_text_chunk
    procedure :: joined => nml_text_joined
    procedure :: value => nml_text_value
    procedure :: raw_value => nml_text_raw_value
  end type nml_text_t

contains

  !> Read the file on rank 0 and broadcast its lines; stat /= 0 on every rank if it fails.
  subroutine nml_text_load(this, path, comm, stat, msg)
    class(nml_text_t), intent(inout) :: this
    character(len=*), intent(in) :: path
    type(MPI_Comm), intent(in) :: comm
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer :: rank, unit, ios, info(2), n
    character(len=line_len) :: buf
    logical :: too_long
    character(len=256) :: iom
    character(len=:), allocatable :: why

    call MPI_Comm_rank(comm, rank)
    this%path = path
    info = 0
    msg = ''
    if (rank == 0) then
      ! a folder or a pipe would open, then read nothing or block: look first
      why = why_not_readable(path)
      if (len(why) == 0) then
        open(newunit=unit, file=path, status='old', action='read', iostat=ios, iomsg=iom)
        if (ios /= 0) why = trim(iom)
      end if
      if (len(why) > 0) then
        info(1) = 1
        info(2) = 0
        if (why == 'it is a folder') info(2) = 1
        if (why(1:min(len(why), 17)) == 'it is not a regul') info(2) = 2
        if (why == 'no such file') info(2) = 3
      else
        n = 0
        do
          call read_line(unit, buf, ios, too_long)
          if (ios /= 0) exit
          n = n + 1
          if (too_long .and. info(1) == 0) then
            info(1) = 2
            info(2) = n
          end if
        end do
        if (info(1) == 0) then
          info(2) = n
          allocate(this%lines(n))
          rewind(unit)
          do n = 1, info(2)
            call read_line(unit, this%lines(n), ios, too_long)
          end do
        end if
        close(unit)
      end if
    end if
    call MPI_Bcast(info, 2, MPI_INTEGER, 0, comm)
    stat = info(1)
    if (stat == 1) then
      ! the reason travels as a code: rank 0 alone looked at the file
      select case (info(2))
      case (1)
        msg = "cannot open the input file '"//trim(path)//"': it is a folder"
      case (2)
        msg = "cannot open the input file '"//trim(path)//"': it is not a regular file "// &
              "(a device, pipe or socket)"
      case (3)
        msg = "cannot open the input file '"//trim(path)//"': no such file"
      case default
        msg = "cannot open the input file '"//trim(path)//"': it cannot be read"
      end select
      return
    else if (stat == 2) then
      msg = "input file '"//trim(path)//"': line "//itoa(info(2))// &
            ' is longer than 512 characters'
      return
    end if
    this%n_lines = info(2)
    if (rank /= 0) allocate(this%lines(this%n_lines))
    if (this%n_lines > 0) call MPI_Bcast(this%lines, line_len*this%n_lines, MPI_CHARACTER, 0, comm)
  end subroutine nml_text_load

  !> Read one line into buf; too_long when anything but blanks follows past len(buf)
  !> (a plain read would cut it silently); ios /= 0 at the end of the file.
  subroutine read_line(unit, buf, ios, too_long)
    integer, intent(in) :: unit
    character(len=*), intent(out) :: buf
    integer, intent(out) :: ios
    logical, intent(out) :: too_long
    character(len=256) :: rest
    integer :: got
    too_long = .false.
    read(unit, '(a)', advance='no', iostat=ios, size=got) buf
    if (is_iostat_eor(ios)) then
      ios = 0
      return
    end if
    if (ios /= 0) return
    do
      read(unit, '(a)', advance='no', iostat=ios, size=got) rest
      if (len_trim(rest(1:got)) > 0) too_long = .true.
      if (ios /= 0) exit
    end do
    ios = 0
  end subroutine read_line

  !> Split the text into groups and record each assigned variable; stat /= 0 on a syntax error.
  subroutine nml_text_scan(this, stat, msg)
    class(nml_text_t), intent(inout) :: this
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer :: l, i, n, j, k, j0, ns
    logical :: in_group, in_quote, doubled
    character :: q, c
    character(len=key_len) :: ident, sub
    type(nml_group_t), allocatable :: tmp(:)

    stat = 0
    msg = ''
    do l = 1, this%n_lines
      ! a Windows line end is a blank; other control bytes would reach file names silently
      do i = 1, len_trim(this%lines(l))
        k = iachar(this%lines(l)(i:i))
        if (k == 13) this%lines(l)(i:i) = ' '
        if (k < 32 .and. k /= 9 .and. k /= 13) then
          stat = 1
          msg = 'line '//itoa(l)//', column '//itoa(i)//': a control character (byte '// &
                itoa(k)//') is not allowed in an input file'
          return
        end if
      end do
    end do
    allocate(this%groups(8))
    this%n_groups = 0
    in_group = .false.
    in_quote = .false.
    q = ' '
    do l = 1, this%n_lines
      n = len_trim(this%lines(l))
      i = 1
      do while (i <= n)
        c = char_at(this%lines(l), i)
        if (in_quote) then
          if (c == q) then
            ! (a doubled quote; i + 1 <= n read only when i < n: .and. may evaluate both)
            doubled = .false.
            if (i < n) doubled = this%lines(l)(i+1:i+1) == q
            if (doubled) then
              i = i + 1
            else
              in_quote = .false.
            end if
          end if
          i = i + 1
          cycle
        end if
        if (c == '!') exit
        if (.not. in_group) then
          if (c == '&' .or. c == '$') then
            j = i + 1
            call read_ident(this%lines(l), j, ident)
            if (len_trim(ident) == 0) then
              stat = 1
              msg = 'line '//itoa(l)//": '&' without a group name"
              return
            end if
            if (this%n_groups == size(this%groups)) then
              allocate(tmp(2*size(this%groups)))
              tmp(1:this%n_groups) = this%groups(1:this%n_groups)
              call move_alloc(tmp, this%groups)
            end if
            this%n_groups = this%n_groups + 1
            associate(g => this%groups(this%n_groups))
              g%name = ident
              g%first_line = l
              g%first_col = i
              allocate(g%keys(16), g%subs(16), g%key_lines(16), g%key_cols(16))
              g%n_keys = 0
            end associate
            in_group = .true.
            i = j
            cycle
          else if (c /= ' ' .and. c /= achar(9)) then
            stat = 1
            msg = 'line '//itoa(l)//': text outside any namelist group: "'// &
                  trim(adjustl(this%lines(l)))//'"'
            return
          end if
          i = i + 1
          cycle
        end if
        ! inside a group
        if (c == "'" .or. c == '"') then
          in_quote = .true.
          q = c
        else if (c == '/' .or. c == '&' .or. c == '$') then
          if (c /= '/') then
            j = i + 1
            call read_ident(this%lines(l), j, ident)
            if (ident /= 'end') then
              stat = 1
              msg = 'line '//itoa(l)//': &'//trim(this%groups(this%n_groups)%name)// &
                    " is not closed with '/' before a new group starts"
              return
            end if
            i = j - 1
          end if
          this%groups(this%n_groups)%last_line = l
          this%groups(this%n_groups)%last_col = i
          in_group = .false.
        else if (is_ident_start(c) .and. .not. after_ident_char(this%lines(l), i)) then
          j = i
          call read_ident(this%lines(l), j, ident)
          k = j
          sub = ''
          ! skip an array index such as box(1) and blanks
          if (k <= n) then
            if (this%lines(l)(k:k) == '(') then
              j0 = k
              do while (k <= n)
                if (this%lines(l)(k:k) == ')') exit
                k = k + 1
              end do
              ns = min(k, n, j0 + key_len - 1) - j0 + 1
              sub(1:ns) = this%lines(l)(j0:j0 + ns - 1)
              k = k + 1
            end if
          end if
          do while (k <= n)
            if (this%lines(l)(k:k) /= ' ') exit
            k = k + 1
          end do
          if (k <= n) then
            if (this%lines(l)(k:k) == '=') then
              call check_assignment(this, this%n_groups, ident, sub, l, k, stat, msg)
              if (stat /= 0) return
              call add_key(this%groups(this%n_groups), ident, sub, l, k)
            end if
          end if
          i = j
          cycle
        end if
        i = i + 1
      end do
      if (in_quote) then
        stat = 1
        msg = 'line '//itoa(l)//': a quoted string is not closed on its line'
        return
      end if
    end do
    if (in_group) then
      stat = 1
      msg = '&'//trim(this%groups(this%n_groups)%name)//' (opened on line '// &
            itoa(this%groups(this%n_groups)%first_line)//") is never closed with '/'"
    end if
  end subroutine nml_text_scan

  !> The lines of group g, with anything outside the group blanked, for an internal read.
  subroutine nml_text_chunk(this, g, chunk)
    class(nml_text_t), intent(in) :: this
    integer, intent(in) :: g
    character(len=line_len), allocatable, intent(out) :: chunk(:)
    integer :: n
    associate(grp => this%groups(g))
      n = grp%last_line - grp%first_line + 1
      allocate(chunk(n))
      chunk(:) = this%lines(grp%first_line:grp%last_line)
      chunk(n)(grp%last_col + 1:) = ''
      if (grp%first_col > 1) chunk(1)(1:grp%first_col - 1) = ''
    end associate
  end subroutine nml_text_chunk

  !> The whole file as one string with newlines, as stored in the output file.
  function nml_text_joined(this) result(text)
    class(nml_text_t), intent(in) :: this
    character(len=:), allocatable :: text
    integer :: l
    text = ''
    do l = 1, this%n_lines
      text = text//trim(this%lines(l))//new_line('a')
    end do
  end function nml_text_joined

  subroutine add_key(g, key, sub, line, col)
    type(nml_group_t), intent(inout) :: g
    character(len=*), intent(in) :: key, sub
    integer, intent(in) :: line, col
    character(len=key_len), allocatable :: k2(:), s2(:)
    integer, allocatable :: l2(:), c2(:)
    if (g%n_keys == size(g%keys)) then
      allocate(k2(2*g%n_keys), s2(2*g%n_keys), l2(2*g%n_keys), c2(2*g%n_keys))
      k2(1:g%n_keys) = g%keys
      s2(1:g%n_keys) = g%subs
      l2(1:g%n_keys) = g%key_lines
      c2(1:g%n_keys) = g%key_cols
      call move_alloc(k2, g%keys)
      call move_alloc(s2, g%subs)
      call move_alloc(l2, g%key_lines)
      call move_alloc(c2, g%key_cols)
    end if
    g%n_keys = g%n_keys + 1
    g%keys(g%n_keys) = key
    g%subs(g%n_keys) = sub
    g%key_lines(g%n_keys) = line
    g%key_cols(g%n_keys) = col
  end subroutine add_key

  !> The value of assignment k of group g as written: a quoted string whole (quotes
  !> included, to its closing quote on its line), else its first token.
  function nml_text_raw_value(this, g, k) result(raw)
    class(nml_text_t), intent(in) :: this
    integer, intent(in) :: g, k
    character(len=:), allocatable :: raw
    character :: q
    integer :: l, i, j, n
    call value_start(this, g, k, l, i)
    raw = ''
    if (l > this%n_lines) return
    n = len_trim(this%lines(l))
    q = char_at(this%lines(l), i)
    if (q /= "'" .and. q /= '"') then
      raw = this%value(g, k)
      return
    end if
    j = i + 1
    do while (j <= n)
      if (this%lines(l)(j:j) == q) then
        if (j == n) exit
        if (this%lines(l)(j+1:j+1) /= q) exit
        j = j + 1
      end if
      j = j + 1
    end do
    raw = this%lines(l)(i:min(j, n))
  end function nml_text_raw_value

  !> The first value token of assignment k of group g, as written (up to a blank, ',' or '/').
  function nml_text_value(this, g, k) result(token)
    class(nml_text_t), intent(in) :: this
    integer, intent(in) :: g, k
    character(len=:), allocatable :: token
    integer :: l, i, j
    call value_start(this, g, k, l, i)
    token = ''
    if (l > this%n_lines) return
    j = scan(this%lines(l)(i:), ' ,/'//achar(9))
    if (j == 0) then
      token = trim(this%lines(l)(i:))
    else
      token = this%lines(l)(i:i + j - 2)
    end if
  end function nml_text_value

  !> Line l and column i of the first non-blank character after the '=' of assignment k of
  !> group g (l > n_lines when there is none).
  subroutine value_start(this, g, k, l, i)
    class(nml_text_t), intent(in) :: this
    integer, intent(in) :: g, k
    integer, intent(out) :: l, i
    l = this%groups(g)%key_lines(k)
    i = this%groups(g)%key_cols(k) + 1
    do while (l <= this%n_lines)
      do while (i <= len_trim(this%lines(l)))
        if (this%lines(l)(i:i) /= ' ' .and. this%lines(l)(i:i) /= achar(9)) return
        i = i + 1
      end do
      l = l + 1
      i = 1
    end do
  end subroutine value_start

  !> Refuse an assignment key(sub) = ... (its '=' at column col of line l) of group g that
  !> repeats an earlier one (the last would silently win), or that has no value.
  subroutine check_assignment(this, g, key, sub, l, col, stat, msg)
    class(nml_text_t), intent(in) :: this
    integer, intent(in) :: g, l, col
    character(len=*), intent(in) :: key, sub
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer :: k, m, i, j
    character :: c
    character(len=key_len) :: ident
    stat = 0
    msg = ''
    associate(grp => this%groups(g))
      do k = 1, grp%n_keys
        if (grp%keys(k) /= key) cycle
        if (len_trim(sub) > 0 .and. len_trim(grp%subs(k)) > 0 .and. grp%subs(k) /= sub) cycle
        stat = 1
        msg = 'line '//itoa(l)//': &'//trim(grp%name)//': '//trim(key)//trim(sub)// &
              ' is given twice (first on line '//itoa(grp%key_lines(k))//')'
        return
      end do
    end associate
    call next_nonblank(this, l, col, m, i)
    c = ' '
    if (m <= this%n_lines) c = char_at(this%lines(m), i)
    if (is_ident_start(c)) then
      ! a name followed by '=' is the next assignment: this one has no value
      j = i
      call read_ident(this%lines(m), j, ident)
      do while (j <= len_trim(this%lines(m)))
        if (this%lines(m)(j:j) /= ' ') exit
        j = j + 1
      end do
      if (this%lines(m)(j:j) == '=' .or. this%lines(m)(j:j) == '(') c = ','
    end if
    if (c == ',' .or. c == '/' .or. c == '&' .or. c == '$' .or. c == ' ') then
      stat = 1
      msg = 'line '//itoa(l)//': &'//trim(this%groups(g)%name)//': '//trim(key)//trim(sub)// &
            " has no value after '='"
    end if
  end subroutine check_assignment

  !> Line m and column i of the first non-blank character after column col of line l,
  !> outside comments, looking on into the following lines; m > n_lines at the end.
  subroutine next_nonblank(this, l, col, m, i)
    class(nml_text_t), intent(in) :: this
    integer, intent(in) :: l, col
    integer, intent(out) :: m, i
    i = col + 1
    do m = l, this%n_lines
      if (m > l) i = 1
      do while (i <= len_trim(this%lines(m)))
        if (this%lines(m)(i:i) == '!') exit
        if (this%lines(m)(i:i) /= ' ' .and. this%lines(m)(i:i) /= achar(9)) return
        i = i + 1
      end do
    end do
  end subroutine next_nonblank

  !> Read a lower-cased identifier starting at position j; j ends just past it.
  subroutine read_ident(line, j, ident)
    character(len=*), intent(in) :: line
    integer, intent(inout) :: j
    character(len=*), intent(out) :: ident
    integer :: j0, k, c
    j0 = j
    do while (j <= len_trim(line))
      if (.not. is_ident_char(line(j:j))) exit
      j = j + 1
    end do
    ident = line(j0:j - 1)
    do k = 1, len_trim(ident)
      c = iachar(ident(k:k))
      if (c >= iachar('A') .and. c <= iachar('Z')) ident(k:k) = achar(c + 32)
    end do
  end subroutine read_ident

  !> The character at position i of line (a function: gfortran's -Wcharacter-truncation takes
  !> a one-character substring of an array component for the whole element).
  pure character function char_at(line, i)
    character(len=*), intent(in) :: line
    integer, intent(in) :: i
    char_at = line(i:i)
  end function char_at

  pure logical function is_ident_start(c)
    character, intent(in) :: c
    is_ident_start = (c >= 'a' .and. c <= 'z') .or. (c >= 'A' .and. c <= 'Z')
  end function is_ident_start

  pure logical function is_ident_char(c)
    character, intent(in) :: c
    is_ident_char = is_ident_start(c) .or. (c >= '0' .and. c <= '9') .or. c == '_' .or. c == '%'
  end function is_ident_char

  !> True when position i continues a token (so it cannot start a variable name).
  pure logical function after_ident_char(line, i)
    character(len=*), intent(in) :: line
    integer, intent(in) :: i
    character :: p
    after_ident_char = .false.
    if (i == 1) return
    p = line(i-1:i-1)
    after_ident_char = is_ident_char(p) .or. p == '.' .or. p == '+' .or. p == '-'
  end function after_ident_char

end module iem_namelist_text
