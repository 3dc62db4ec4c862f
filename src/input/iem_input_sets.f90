!> Readers of the repeatable groups that act on node sets: &bc, &load and &probe.
module iem_input_sets
  use iem_kinds, only: wp
  use iem_constants, only: unset_real
  use iem_strings, only: itoa, rtoa, lower
  use iem_config, only: bc_config_t, load_config_t, probe_config_t, node_set_spec_t, name_len
  use iem_namelist_text, only: nml_text_t, line_len
  use iem_input_checks, only: bad, check_keys, read_error, check_reals, check_logicals, &
                              check_strings, check_set, check_tf, check_applies
  implicit none
  private
  public :: read_bc, read_load, read_probe

contains

  ! ----------------------------------------------------------------------------------- &bc
  subroutine parse_bc(chunk, b, ios, iomsg)
    character(len=line_len), intent(in) :: chunk(:)
    type(bc_config_t), intent(inout) :: b
    integer, intent(out) :: ios
    character(len=:), allocatable, intent(out) :: iomsg
    character(len=name_len) :: name
    character(len=8) :: where, kind, dofs, time_function
    real(wp) :: box(4), point(2), velocity(2), t_start, t_ramp, t_release
    real(wp) :: segment(4), center(2), radius, normal(2)
    character(len=name_len) :: shape
    character(len=256) :: m
    namelist /bc/ name, where, box, point, segment, center, radius, shape, normal, kind, dofs, &
      velocity, time_function, t_start, t_ramp, t_release
    name = ''; where = ''; box = unset_real; point = unset_real; kind = 'fix'; dofs = 'xy'
    segment = unset_real; center = unset_real; radius = unset_real; shape = ''
    normal = unset_real
    velocity = 0.0_wp; time_function = 'constant'; t_start = 0.0_wp; t_ramp = 0.0_wp
    t_release = huge(1.0_wp)
    m = ''
    read(chunk, nml=bc, iostat=ios, iomsg=m)
    iomsg = trim(m)
    b%name = name; b%set%where = lower(where); b%set%box = box; b%set%point = point
    call put_set(b%set, segment, center, radius, shape, normal)
    b%kind = lower(kind); b%velocity = velocity
    b%dof(1) = index(lower(dofs), 'x') > 0
    b%dof(2) = index(lower(dofs), 'y') > 0
    if (len_trim(dofs) == 0 .or. verify(trim(lower(dofs)), 'xy') /= 0) b%dof = .false.
    b%tf%kind = lower(time_function); b%tf%t_start = t_start; b%tf%t_ramp = t_ramp
    b%t_release = t_release
  end subroutine parse_bc

  !> Check, parse and validate group g (&bc) of the input into the configuration.
  subroutine read_bc(text, g, ib, b, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g, ib
    type(bc_config_t), intent(inout) :: b
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=:), allocatable :: iomsg, label
    label = '&bc #'//itoa(ib)//' (line '//itoa(text%groups(g)%first_line)//')'
    call check_keys(text, g, [character(len=14) :: 'name', 'where', 'box', 'point', &
      'segment', 'center', 'radius', 'shape', 'normal', 'kind', 'dofs', 'velocity', &
      'time_function', 't_start', 't_ramp', 't_release'], label, stat, msg)
    if (stat /= 0) return
    call text%chunk(g, chunk)
    call parse_bc(chunk, b, stat, iomsg)
    if (stat /= 0) then
      call read_error(text, g, label, iomsg, chunk, try_bc, msg)
      stat = 1
      return
    end if
    call check_strings(text, g, label, [character(len=13) :: 'name', 'where', 'kind', 'dofs', &
      'time_function', 'shape'], [name_len, 8, 8, 8, 8, name_len], stat, msg)
    if (stat == 0) call check_applies(text, g, label, b%set%where, b%tf%kind, stat, msg)
    if (stat /= 0) return
    call check_set_reals(text, g, label, b%set, stat, msg)
    if (stat /= 0) return
    call check_reals(text, g, label, [character(len=9) :: 'velocity', 'velocity', 't_start', &
      't_ramp', 't_release'], [b%velocity, b%tf%t_start, b%tf%t_ramp, b%t_release], stat, msg)
    if (stat /= 0) return
    if (len_trim(b%name) == 0) b%name = 'bc'//itoa(ib)
    call check_set(b%set, label, .false., stat, msg)
    if (stat /= 0) return
    if (b%kind /= 'fix' .and. b%kind /= 'velocity') then
      call bad(label, 'kind', "'"//trim(b%kind)//"'", "must be 'fix' or 'velocity'", stat, msg)
    else if (.not. any(b%dof)) then
      call bad(label, 'dofs', '', "must be 'x', 'y' or 'xy'", stat, msg)
    else if (b%kind == 'fix' .and. any(b%velocity /= 0.0_wp)) then
      call bad(label, 'velocity', rtoa(b%velocity(1))//', '//rtoa(b%velocity(2)), &
               "needs kind = 'velocity'", stat, msg)
    else if (.not. (b%t_release > 0.0_wp)) then
      call bad(label, 't_release', rtoa(b%t_release), 'must be > 0 [s] (omit it: never '// &
               'released)', stat, msg)
    else
      call check_tf(b%tf, label, stat, msg)
    end if
  end subroutine read_bc

  integer function try_bc(part) result(ios)
    character(len=line_len), intent(in) :: part(:)
    type(bc_config_t) :: c
    character(len=:), allocatable :: m
    call parse_bc(part, c, ios, m)
  end function try_bc

  ! --------------------------------------------------------------------------------- &load
  subroutine parse_load(chunk, l, ios, iomsg)
    character(len=line_len), intent(in) :: chunk(:)
    type(load_config_t), intent(inout) :: l
    integer, intent(out) :: ios
    character(len=:), allocatable, intent(out) :: iomsg
    character(len=name_len) :: name
    character(len=8) :: where, kind, time_function
    real(wp) :: box(4), point(2), force(2), traction(2), accel(2), t_start, t_ramp
    real(wp) :: segment(4), center(2), radius, normal(2)
    character(len=name_len) :: shape
    character(len=256) :: m
    namelist /load/ name, kind, where, box, point, segment, center, radius, shape, normal, &
      force, traction, accel, time_function, t_start, t_ramp
    name = ''; kind = 'nodal'; where = ''; box = unset_real; point = unset_real
    segment = unset_real; center = unset_real; radius = unset_real; shape = ''
    normal = unset_real
    force = unset_real; traction = unset_real; accel = unset_real
    time_function = 'constant'; t_start = 0.0_wp; t_ramp = 0.0_wp
    m = ''
    read(chunk, nml=load, iostat=ios, iomsg=m)
    iomsg = trim(m)
    l%name = name; l%kind = lower(kind); l%set%where = lower(where); l%set%box = box
    l%set%point = point
    call put_set(l%set, segment, center, radius, shape, normal)
    select case (trim(l%kind))
    case ('nodal')
      l%value = force
    case ('edge')
      l%value = traction
    case ('gravity')
      l%value = accel
    end select
    ! remember whether the other vectors were given, to refuse them
    if (trim(l%kind) /= 'nodal' .and. any(force /= unset_real)) l%kind = '?force'
    if (trim(l%kind) /= 'edge' .and. any(traction /= unset_real)) l%kind = '?tract'
    if (trim(l%kind) /= 'gravity' .and. any(accel /= unset_real)) l%kind = '?accel'
    l%tf%kind = lower(time_function); l%tf%t_start = t_start; l%tf%t_ramp = t_ramp
  end subroutine parse_load

  !> Check, parse and validate group g (&load) of the input into the configuration.
  subroutine read_load(text, g, il, l, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g, il
    type(load_config_t), intent(inout) :: l
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=:), allocatable :: iomsg, label
    character(len=8) :: vname
    label = '&load #'//itoa(il)//' (line '//itoa(text%groups(g)%first_line)//')'
    call check_keys(text, g, [character(len=14) :: 'name', 'kind', 'where', 'box', 'point', &
      'segment', 'center', 'radius', 'shape', 'normal', 'force', 'traction', 'accel', &
      'time_function', 't_start', 't_ramp'], label, stat, msg)
    if (stat /= 0) return
    call text%chunk(g, chunk)
    call parse_load(chunk, l, stat, iomsg)
    if (stat /= 0) then
      call read_error(text, g, label, iomsg, chunk, try_load, msg)
      stat = 1
      return
    end if
    call check_strings(text, g, label, [character(len=13) :: 'name', 'kind', 'where', &
      'time_function', 'shape'], [name_len, 8, 8, 8, name_len], stat, msg)
    if (stat == 0) call check_applies(text, g, label, l%set%where, l%tf%kind, stat, msg)
    if (stat /= 0) return
    ! the vector of the load's kind (a vector of another kind is refused below)
    vname = merge('force   ', merge('traction', merge('accel   ', '        ', &
      l%kind == 'gravity'), l%kind == 'edge'), l%kind == 'nodal')
    call check_set_reals(text, g, label, l%set, stat, msg)
    if (stat /= 0) return
    call check_reals(text, g, label, [character(len=8) :: vname, vname, 't_start', 't_ramp'], &
      [l%value, l%tf%t_start, l%tf%t_ramp], stat, msg)
    if (stat /= 0) return
    if (len_trim(l%name) == 0) l%name = 'load'//itoa(il)
    select case (trim(l%kind))
    case ('nodal')
      vname = 'force'
    case ('edge')
      vname = 'traction'
    case ('gravity')
      vname = 'accel'
    case ('?force', '?tract', '?accel')
      call bad(label, 'kind', '', "does not match the vector given (force: 'nodal', "// &
               "traction: 'edge', accel: 'gravity')", stat, msg)
      return
    case default
      call bad(label, 'kind', "'"//trim(l%kind)//"'", "must be 'nodal', 'edge' or 'gravity'", &
               stat, msg)
      return
    end select
    if (any(l%value == unset_real)) then
      call bad(label, trim(vname), '(not given)', 'is required for kind = '''//trim(l%kind)// &
               ''' (two components)', stat, msg)
      return
    end if
    if (l%kind == 'gravity') then
      if (len_trim(l%set%where) > 0 .and. l%set%where /= 'all') then
        call bad(label, 'where', "'"//trim(l%set%where)//"'", &
                 "does not apply to gravity (it acts on every node)", stat, msg)
        return
      end if
      l%set%where = 'all'
    end if
    call check_set(l%set, label, l%kind == 'edge', stat, msg)
    if (stat /= 0) return
    call check_tf(l%tf, label, stat, msg)
  end subroutine read_load

  integer function try_load(part) result(ios)
    character(len=line_len), intent(in) :: part(:)
    type(load_config_t) :: c
    character(len=:), allocatable :: m
    call parse_load(part, c, ios, m)
  end function try_load

  ! ---------------------------------------------------------------------- node-set helpers
  !> Store the geometric node-set variables of a &bc or &load read into its set.
  subroutine put_set(set, segment, center, radius, shape, normal)
    type(node_set_spec_t), intent(inout) :: set
    real(wp), intent(in) :: segment(4), center(2), radius, normal(2)
    character(len=*), intent(in) :: shape
    set%segment = segment; set%center = center; set%radius = radius
    set%shape = shape; set%normal = normal
  end subroutine put_set

  !> Refuse a non-finite or out-of-range real of a node set (check_reals on its variables).
  subroutine check_set_reals(text, g, label, set, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    character(len=*), intent(in) :: label
    type(node_set_spec_t), intent(in) :: set
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    call check_reals(text, g, label, [character(len=7) :: 'box', 'box', 'box', 'box', 'point', &
      'point', 'segment', 'segment', 'segment', 'segment', 'center', 'center', 'radius', &
      'normal', 'normal'], [set%box, set%point, set%segment, set%center, set%radius, &
      set%normal], stat, msg)
  end subroutine check_set_reals

  ! -------------------------------------------------------------------------------- &probe
  subroutine parse_probe(chunk, p, ios, iomsg)
    character(len=line_len), intent(in) :: chunk(:)
    type(probe_config_t), intent(inout) :: p
    integer, intent(out) :: ios
    character(len=:), allocatable, intent(out) :: iomsg
    character(len=name_len) :: name
    real(wp) :: x, y
    logical :: springs
    character(len=256) :: m
    namelist /probe/ name, x, y, springs
    name = ''; x = unset_real; y = unset_real; springs = .false.
    m = ''
    read(chunk, nml=probe, iostat=ios, iomsg=m)
    iomsg = trim(m)
    p%name = name; p%x = x; p%y = y; p%springs = springs
  end subroutine parse_probe

  !> Check, parse and validate group g (&probe) of the input into the configuration.
  subroutine read_probe(text, g, ip, p, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g, ip
    type(probe_config_t), intent(inout) :: p
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=:), allocatable :: iomsg, label
    label = '&probe #'//itoa(ip)//' (line '//itoa(text%groups(g)%first_line)//')'
    call check_keys(text, g, [character(len=8) :: 'name', 'x', 'y', 'springs'], label, stat, &
                    msg)
    if (stat /= 0) return
    call text%chunk(g, chunk)
    call parse_probe(chunk, p, stat, iomsg)
    if (stat /= 0) then
      call read_error(text, g, label, iomsg, chunk, try_probe, msg)
      stat = 1
      return
    end if
    call check_strings(text, g, label, ['name'], [name_len], stat, msg)
    if (stat /= 0) return
    call check_reals(text, g, label, ['x', 'y'], [p%x, p%y], stat, msg)
    if (stat == 0) call check_logicals(text, g, label, ['springs'], stat, msg)
    if (stat /= 0) return
    if (len_trim(p%name) == 0) then
      call bad(label, 'name', "''", 'is required', stat, msg)
    else if (verify(trim(p%name), 'abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ'// &
                    '0123456789_-.') /= 0) then
      call bad(label, 'name', "'"//trim(p%name)//"'", &
               'may hold only letters, digits, _ - and .', stat, msg)
    else if (p%x == unset_real) then
      call bad(label, 'x', '(not given)', 'is required [m]', stat, msg)
    else if (p%y == unset_real) then
      call bad(label, 'y', '(not given)', 'is required [m]', stat, msg)
    end if
  end subroutine read_probe

  integer function try_probe(part) result(ios)
    character(len=line_len), intent(in) :: part(:)
    type(probe_config_t) :: c
    character(len=:), allocatable :: m
    call parse_probe(part, c, ios, m)
  end function try_probe

end module iem_input_sets
