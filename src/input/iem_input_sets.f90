!> Readers of the repeatable groups that act on node sets: &bc, &load and &probe.
module iem_input_sets
  use iem_kinds, only: wp
  use iem_constants, only: unset_real
  use iem_strings, only: itoa, rtoa, lower
  use iem_config, only: bc_config_t, load_config_t, probe_config_t, node_set_spec_t, name_len
  use iem_namelist_text, only: nml_text_t, line_len
  use iem_input_checks, only: bad, check_set, check_tf, check_applies
  use iem_input_table, only: key_t, key, key_only, read_group, check_literals, check_values
  implicit none
  private
  public :: read_bc, read_load, read_probe

contains

  ! ----------------------------------------------------------------------------------- &bc
  subroutine parse_bc(chunk, b, ios, iomsg)
    character(len=line_len), intent(in) :: chunk(:)
    type(bc_config_t), intent(inout) :: b
    integer, intent(out) :: ios
    character(len=256), intent(out) :: iomsg
    character(len=name_len) :: name
    character(len=8) :: where, kind, dofs, time_function
    real(wp) :: box(4), point(2), velocity(2), t_start, t_ramp, t_release
    real(wp) :: segment(4), center(2), radius, normal(2)
    character(len=name_len) :: shape
    namelist /bc/ name, where, box, point, segment, center, radius, shape, normal, kind, dofs, &
      velocity, time_function, t_start, t_ramp, t_release
    name = ''; where = ''; box = unset_real; point = unset_real; kind = 'fix'; dofs = 'xy'
    segment = unset_real; center = unset_real; radius = unset_real; shape = ''
    normal = unset_real
    velocity = unset_real; time_function = 'constant'; t_start = 0.0_wp; t_ramp = 0.0_wp
    t_release = huge(1.0_wp)
    iomsg = ''
    read(chunk, nml=bc, iostat=ios, iomsg=iomsg)
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
    type(bc_config_t), intent(inout), target :: b
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=256) :: iomsg
    character(len=:), allocatable :: label
    type(key_t) :: keys(16)
    label = '&bc #'//itoa(ib)//' (line '//itoa(text%groups(g)%first_line)//')'
    keys = [key('name', b%name), set_keys(b%set), key('kind', b%kind, allowed='fix velocity'), &
      key_only('dofs', 's', 8), key('velocity', b%velocity), &
      key('time_function', b%tf%kind), key('t_start', b%tf%t_start), &
      key('t_ramp', b%tf%t_ramp), &
      key('t_release', b%t_release, range='> 0', unit=' [s] (omit it: never released)')]
    call read_group(text, g, keys, label, try_bc, chunk, stat, msg)
    if (stat /= 0) return
    call parse_bc(chunk, b, stat, iomsg)
    call check_applies(text, g, label, b%set%where, b%tf%kind, stat, msg)
    if (stat /= 0) return
    ! velocity: two values, or none (0, 0)
    if (count(b%velocity == unset_real) == 1) then
      call bad(label, 'velocity', rtoa(merge(b%velocity(1), b%velocity(2), &
               b%velocity(1) /= unset_real)), 'needs two values (vx, vy) [m/s]', stat, msg)
      return
    end if
    if (all(b%velocity == unset_real)) b%velocity = 0.0_wp
    call check_literals(text, g, keys, label, stat, msg)
    if (stat /= 0) return
    if (len_trim(b%name) == 0) b%name = 'bc'//itoa(ib)
    call check_set(b%set, label, .false., stat, msg)
    if (stat == 0) call check_values(keys, 'kind', label, stat, msg)
    if (stat /= 0) return
    if (.not. any(b%dof)) then
      call bad(label, 'dofs', '', "must be 'x', 'y' or 'xy'", stat, msg)
    else if (b%kind == 'fix' .and. any(b%velocity /= 0.0_wp)) then
      call bad(label, 'velocity', rtoa(b%velocity(1))//', '//rtoa(b%velocity(2)), &
               "needs kind = 'velocity'", stat, msg)
    else
      call check_values(keys, 't_release', label, stat, msg)
      if (stat == 0) call check_tf(b%tf, label, stat, msg)
    end if
  end subroutine read_bc

  integer function try_bc(part, iomsg) result(ios)
    character(len=line_len), intent(in) :: part(:)
    character(len=256), intent(out) :: iomsg
    type(bc_config_t) :: c
    call parse_bc(part, c, ios, iomsg)
  end function try_bc

  ! --------------------------------------------------------------------------------- &load
  subroutine parse_load(chunk, l, ios, iomsg)
    character(len=line_len), intent(in) :: chunk(:)
    type(load_config_t), intent(inout) :: l
    integer, intent(out) :: ios
    character(len=256), intent(out) :: iomsg
    character(len=name_len) :: name
    character(len=8) :: where, kind, time_function
    real(wp) :: box(4), point(2), force(2), traction(2), accel(2), t_start, t_ramp
    real(wp) :: segment(4), center(2), radius, normal(2)
    character(len=name_len) :: shape
    namelist /load/ name, kind, where, box, point, segment, center, radius, shape, normal, &
      force, traction, accel, time_function, t_start, t_ramp
    name = ''; kind = 'nodal'; where = ''; box = unset_real; point = unset_real
    segment = unset_real; center = unset_real; radius = unset_real; shape = ''
    normal = unset_real
    force = unset_real; traction = unset_real; accel = unset_real
    time_function = 'constant'; t_start = 0.0_wp; t_ramp = 0.0_wp
    iomsg = ''
    read(chunk, nml=load, iostat=ios, iomsg=iomsg)
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
    type(load_config_t), intent(inout), target :: l
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=256) :: iomsg
    character(len=:), allocatable :: label
    character(len=8) :: vname
    type(key_t) :: keys(16)
    label = '&load #'//itoa(il)//' (line '//itoa(text%groups(g)%first_line)//')'
    call read_group(text, g, load_keys(), label, try_load, chunk, stat, msg)
    if (stat /= 0) return
    call parse_load(chunk, l, stat, iomsg)
    ! the table once the kind is known: only the vector of the load's kind is checked as a
    ! real (a vector of another kind is refused below)
    keys = load_keys()
    call check_applies(text, g, label, l%set%where, l%tf%kind, stat, msg)
    if (stat == 0) call check_literals(text, g, keys, label, stat, msg)
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
  contains
    !> The table of &load's variables; the vector of the load's kind is kept in l%value.
    function load_keys() result(keys)
      type(key_t) :: keys(16)
      keys = [key('name', l%name), key('kind', l%kind), set_keys(l%set), &
        vector('force', 'nodal'), vector('traction', 'edge'), vector('accel', 'gravity'), &
        key('time_function', l%tf%kind), key('t_start', l%tf%t_start), &
        key('t_ramp', l%tf%t_ramp)]
    end function load_keys

    type(key_t) function vector(name, kind)
      character(len=*), intent(in) :: name, kind
      vector = key_only(name, 'r')
      if (l%kind == kind) vector = key(name, l%value)
    end function vector
  end subroutine read_load

  integer function try_load(part, iomsg) result(ios)
    character(len=line_len), intent(in) :: part(:)
    character(len=256), intent(out) :: iomsg
    type(load_config_t) :: c
    call parse_load(part, c, ios, iomsg)
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

  !> The table entries of the node-set variables of a &bc or &load, kept in set.
  function set_keys(set) result(keys)
    type(node_set_spec_t), intent(in), target :: set
    type(key_t) :: keys(8)
    keys = [key('where', set%where), key('box', set%box), key('point', set%point), &
      key('segment', set%segment), key('center', set%center), key('radius', set%radius), &
      key('shape', set%shape), key('normal', set%normal)]
  end function set_keys

  ! -------------------------------------------------------------------------------- &probe
  subroutine parse_probe(chunk, p, ios, iomsg)
    character(len=line_len), intent(in) :: chunk(:)
    type(probe_config_t), intent(inout) :: p
    integer, intent(out) :: ios
    character(len=256), intent(out) :: iomsg
    character(len=name_len) :: name
    real(wp) :: x, y
    logical :: springs
    namelist /probe/ name, x, y, springs
    name = ''; x = unset_real; y = unset_real; springs = .false.
    iomsg = ''
    read(chunk, nml=probe, iostat=ios, iomsg=iomsg)
    p%name = name; p%x = x; p%y = y; p%springs = springs
  end subroutine parse_probe

  !> Check, parse and validate group g (&probe) of the input into the configuration.
  subroutine read_probe(text, g, ip, p, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g, ip
    type(probe_config_t), intent(inout), target :: p
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=256) :: iomsg
    character(len=:), allocatable :: label
    type(key_t) :: keys(4)
    label = '&probe #'//itoa(ip)//' (line '//itoa(text%groups(g)%first_line)//')'
    keys = [key('name', p%name), key('x', p%x, need=' [m]'), key('y', p%y, need=' [m]'), &
      key('springs', p%springs)]
    call read_group(text, g, keys, label, try_probe, chunk, stat, msg)
    if (stat /= 0) return
    call parse_probe(chunk, p, stat, iomsg)
    call check_literals(text, g, keys, label, stat, msg)
    if (stat /= 0) return
    if (len_trim(p%name) == 0) then
      call bad(label, 'name', "''", 'is required', stat, msg)
    else if (verify(trim(p%name), 'abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ'// &
                    '0123456789_-.') /= 0) then
      call bad(label, 'name', "'"//trim(p%name)//"'", &
               'may hold only letters, digits, _ - and .', stat, msg)
    else
      call check_values(keys, 'x y', label, stat, msg)
    end if
  end subroutine read_probe

  integer function try_probe(part, iomsg) result(ios)
    character(len=line_len), intent(in) :: part(:)
    character(len=256), intent(out) :: iomsg
    type(probe_config_t) :: c
    call parse_probe(part, c, ios, iomsg)
  end function try_probe

end module iem_input_sets
