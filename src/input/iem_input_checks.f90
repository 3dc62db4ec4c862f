!> Checks and messages shared by the readers of the namelist groups: the standard message
!> for a bad value, unreadable lines, variables that do not apply, node sets and time
!> functions (the checks a group's table drives are in iem_input_table).
module iem_input_checks
  use iem_kinds, only: wp
  use iem_constants, only: unset_real
  use iem_strings, only: itoa, rtoa
  use iem_config, only: node_set_spec_t, time_function_spec_t
  use iem_namelist_text, only: nml_text_t, line_len
  implicit none
  private
  public :: bad, read_error, group_try, given, check_applies, check_set, check_tf

  abstract interface
    !> Read part of one group's text into throw-away variables; returns the iostat.
    integer function group_try(part, iomsg) result(ios)
      import :: line_len
      character(len=line_len), intent(in) :: part(:)
      character(len=256), intent(out) :: iomsg
    end function group_try
  end interface

contains

  !> Compose the standard message for a bad value.
  subroutine bad(label, var, value, why, stat, msg)
    character(len=*), intent(in) :: label, var, value, why
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    stat = 1
    if (len(value) > 0) then
      msg = label//': '//var//' = '//value//' '//why
    else
      msg = label//': '//var//' '//why
    end if
  end subroutine bad

  !> Turn a failed namelist read into a message that names the line and its text.
  subroutine read_error(text, g, label, iomsg, chunk, try, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    character(len=*), intent(in) :: label, iomsg
    character(len=line_len), intent(in) :: chunk(:)
    procedure(group_try) :: try
    character(len=:), allocatable, intent(out) :: msg
    integer :: bad
    bad = find_bad_line(chunk, try)
    if (bad > 0) then
      msg = label//': cannot read line '//itoa(text%groups(g)%first_line + bad - 1)//' "'// &
            trim(adjustl(chunk(bad)))//'": a value of the wrong type or too many values ('// &
            trim(iomsg)//')'
    else
      msg = label//' (lines '//itoa(text%groups(g)%first_line)//'-'// &
            itoa(text%groups(g)%last_line)//'): '//trim(iomsg)
    end if
  end subroutine read_error

  !> The first line of a group's chunk whose inclusion makes the group unreadable (0: none).
  integer function find_bad_line(chunk, try) result(bad)
    character(len=line_len), intent(in) :: chunk(:)
    procedure(group_try) :: try
    character(len=line_len), allocatable :: part(:)
    character(len=256) :: iomsg
    integer :: n, ios
    bad = 0
    do n = 1, size(chunk)
      allocate(part(n + 1))
      part(1:n) = chunk(1:n)
      part(n + 1) = '/'
      ios = try(part, iomsg)
      deallocate(part)
      if (ios /= 0) then
        bad = n
        return
      end if
    end do
  end function find_bad_line

  !> True when group g assigns the variable name (whole or an element).
  logical function given(text, g, name)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    character(len=*), intent(in) :: name
    given = findloc(text%groups(g)%keys(1:text%groups(g)%n_keys), name, 1) > 0
  end function given

  !> Refuse a node-set or time-function variable of group g that the chosen where or
  !> time_function does not use (it would be silently ignored).
  subroutine check_applies(text, g, label, where, time_function, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    character(len=*), intent(in) :: label, where, time_function
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    ! each node-set variable and the where it belongs to
    character(len=*), parameter :: keys(*) = [character(len=8) :: 'box', 'point', 'segment', &
      'center', 'radius', 'shape', 'normal']
    character(len=*), parameter :: wheres(*) = [character(len=8) :: 'box', 'point', &
      'segment', 'circle', 'circle', 'shape', 'face']
    integer :: k
    stat = 0
    msg = ''
    do k = 1, size(keys)
      if (given(text, g, trim(keys(k))) .and. trim(where) /= trim(wheres(k))) then
        call bad(label, trim(keys(k)), '', "applies only to where = '"//trim(wheres(k))// &
                 "' (where = '"//trim(where)//"')", stat, msg)
        return
      end if
    end do
    if (given(text, g, 't_ramp') .and. trim(time_function) /= 'ramp') then
      call bad(label, 't_ramp', '', "applies only to time_function = 'ramp' (time_function = '"// &
               trim(time_function)//"')", stat, msg)
    end if
  end subroutine check_applies

  !> Validate a node-set description (docs/input.md, "Node sets"); edge: the set of an edge
  !> load (a traction on the boundary edges between its nodes), which refuses 'point' and
  !> 'all'. A 'face' normal is scaled to unit length; a 'shape' name is resolved later.
  subroutine check_set(s, label, edge, stat, msg)
    type(node_set_spec_t), intent(inout) :: s
    character(len=*), intent(in) :: label
    logical, intent(in) :: edge
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=*), parameter :: all_wheres = "'left', 'right', 'bottom', 'top', 'box', "// &
      "'point', 'segment', 'circle', 'boundary', 'shape', 'face' or 'all'"
    real(wp) :: n
    stat = 0
    msg = ''
    if (edge .and. (s%where == 'point' .or. s%where == 'all')) then
      call bad(label, 'where', "'"//trim(s%where)//"'", "cannot carry a traction (kind = "// &
               "'edge' acts on the boundary edges between nodes of the set): use another "// &
               "where, or kind = 'nodal'", stat, msg)
      return
    end if
    select case (trim(s%where))
    case ('left', 'right', 'bottom', 'top', 'all', 'boundary')
      continue
    case ('box')
      if (any(s%box == unset_real)) then
        call bad(label, 'box', '(not given)', "is required with where = 'box': "// &
                 'xmin, xmax, ymin, ymax [m]', stat, msg)
      else if (s%box(1) > s%box(2) .or. s%box(3) > s%box(4)) then
        call bad(label, 'box', rtoa(s%box(1))//', '//rtoa(s%box(2))//', '//rtoa(s%box(3))// &
                 ', '//rtoa(s%box(4)), 'needs xmin <= xmax and ymin <= ymax', stat, msg)
      end if
    case ('point')
      if (any(s%point == unset_real)) then
        call bad(label, 'point', '(not given)', "is required with where = 'point': x, y [m]", &
                 stat, msg)
      end if
    case ('segment')
      if (any(s%segment == unset_real)) then
        call bad(label, 'segment', '(not given)', "is required with where = 'segment': "// &
                 'x0, y0, x1, y1 [m]', stat, msg)
      else if (s%segment(1) == s%segment(3) .and. s%segment(2) == s%segment(4)) then
        call bad(label, 'segment', rtoa(s%segment(1))//', '//rtoa(s%segment(2))//', '// &
                 rtoa(s%segment(3))//', '//rtoa(s%segment(4)), "has both ends at one "// &
                 "point (use where = 'point')", stat, msg)
      end if
    case ('circle')
      if (any(s%center == unset_real)) then
        call bad(label, 'center', '(not given)', "is required with where = 'circle': x, y [m]", &
                 stat, msg)
      else if (s%radius == unset_real) then
        call bad(label, 'radius', '(not given)', "is required with where = 'circle' [m]", &
                 stat, msg)
      else if (.not. (s%radius > 0.0_wp)) then
        call bad(label, 'radius', rtoa(s%radius), 'must be > 0 [m]', stat, msg)
      end if
    case ('shape')
      if (len_trim(s%shape) == 0) call bad(label, 'shape', '(not given)', "is required "// &
        "with where = 'shape': the name of a &shape", stat, msg)
    case ('face')
      if (any(s%normal == unset_real)) then
        call bad(label, 'normal', '(not given)', "is required with where = 'face': nx, ny", &
                 stat, msg)
      else
        n = hypot(s%normal(1), s%normal(2))
        if (.not. (n > 0.0_wp)) then
          call bad(label, 'normal', rtoa(s%normal(1))//', '//rtoa(s%normal(2)), &
                   'must be a nonzero vector', stat, msg)
        else
          s%normal = s%normal/n
        end if
      end if
    case ('')
      call bad(label, 'where', "''", 'is required: '//all_wheres, stat, msg)
    case default
      call bad(label, 'where', "'"//trim(s%where)//"'", 'must be '//all_wheres, stat, msg)
    end select
  end subroutine check_set

  !> Validate a time function.
  subroutine check_tf(tf, label, stat, msg)
    type(time_function_spec_t), intent(in) :: tf
    character(len=*), intent(in) :: label
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    stat = 0
    msg = ''
    select case (trim(tf%kind))
    case ('constant', 'step')
      if (.not. (tf%t_start >= 0.0_wp)) call bad(label, 't_start', rtoa(tf%t_start), &
        'must be >= 0 [s]', stat, msg)
    case ('ramp')
      if (.not. (tf%t_start >= 0.0_wp)) then
        call bad(label, 't_start', rtoa(tf%t_start), 'must be >= 0 [s]', stat, msg)
      else if (.not. (tf%t_ramp > 0.0_wp)) then
        call bad(label, 't_ramp', rtoa(tf%t_ramp), "must be > 0 [s] for time_function = 'ramp'", &
                 stat, msg)
      end if
    case default
      call bad(label, 'time_function', "'"//trim(tf%kind)//"'", &
               "must be 'constant', 'step' or 'ramp'", stat, msg)
    end select
  end subroutine check_tf
end module iem_input_checks
