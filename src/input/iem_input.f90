!> Reads the namelist input: rank 0 reads the file, every rank parses the same broadcast text
!> and validates it, so that all ranks agree on every error. Errors name group, variable, value.
module iem_input
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use mpi_f08, only: MPI_Comm, MPI_Comm_rank, MPI_Bcast, MPI_INTEGER
  use iem_kinds, only: wp
  use iem_constants, only: unset_real
  use iem_strings, only: itoa, rtoa, lower
  use iem_config, only: config_t, bc_config_t, load_config_t, probe_config_t, &
                        node_set_spec_t, time_function_spec_t, name_len, path_len
  use iem_namelist_text, only: nml_text_t, line_len
  implicit none
  private
  public :: read_config

  character(len=*), parameter :: known_groups(*) = [character(len=8) :: &
    'run', 'geometry', 'material', 'damping', 'bc', 'load', 'probe', 'static', 'initial']
  logical, parameter :: repeatable(*) = [.false., .false., .false., .false., .true., .true., &
    .true., .false., .false.]
  logical, parameter :: required(*) = [.true., .true., .true., .false., .false., .false., &
    .false., .false., .false.]

contains

  !> Read, parse and validate the namelist file; collective; stat /= 0 with msg on every rank.
  subroutine read_config(path, comm, cfg, stat, msg)
    character(len=*), intent(in) :: path
    type(MPI_Comm), intent(in) :: comm
    type(config_t), intent(out) :: cfg
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    type(nml_text_t) :: text
    integer :: g, k, count(size(known_groups)), ib, il, ip

    cfg%input_file = path
    call text%load(path, comm, stat, msg)
    if (stat /= 0) return
    call text%scan(stat, msg)
    if (stat /= 0) then
      msg = trim(path)//': '//msg
      return
    end if
    cfg%input_text = text%joined()

    count = 0
    do g = 1, text%n_groups
      k = findloc(known_groups, trim(text%groups(g)%name), 1)
      if (k == 0) then
        call fail('unknown namelist group &'//trim(text%groups(g)%name)//' on line '// &
                  itoa(text%groups(g)%first_line)//' (known groups: &run, &geometry, '// &
                  '&material, &damping, &bc, &load, &probe, &static, &initial)')
        return
      end if
      count(k) = count(k) + 1
      if (count(k) > 1 .and. .not. repeatable(k)) then
        call fail('&'//trim(known_groups(k))//' is given twice (second on line '// &
                  itoa(text%groups(g)%first_line)//')')
        return
      end if
    end do
    do k = 1, size(known_groups)
      if (required(k) .and. count(k) == 0) then
        call fail('required namelist group &'//trim(known_groups(k))//' is missing')
        return
      end if
    end do
    allocate(cfg%bcs(count(5)), cfg%loads(count(6)), cfg%probes(count(7)))

    ib = 0; il = 0; ip = 0
    do g = 1, text%n_groups
      select case (trim(text%groups(g)%name))
      case ('run')
        call read_run(text, g, cfg, stat, msg)
      case ('geometry')
        call read_geometry(text, g, cfg, stat, msg)
      case ('material')
        call read_material(text, g, cfg, stat, msg)
      case ('damping')
        call read_damping(text, g, cfg, stat, msg)
      case ('bc')
        ib = ib + 1
        call read_bc(text, g, ib, cfg%bcs(ib), stat, msg)
      case ('load')
        il = il + 1
        call read_load(text, g, il, cfg%loads(il), stat, msg)
      case ('probe')
        ip = ip + 1
        call read_probe(text, g, ip, cfg%probes(ip), stat, msg)
      case ('static')
        call read_static(text, g, cfg, stat, msg)
      case ('initial')
        call read_initial(text, g, cfg, stat, msg)
      end select
      if (stat /= 0) then
        msg = trim(path)//': '//msg
        return
      end if
    end do
    call check_cross(cfg, stat, msg)
    if (stat /= 0) then
      msg = trim(path)//': '//msg
      return
    end if
    call check_files(cfg, comm, stat, msg)

  contains

    subroutine fail(text_)
      character(len=*), intent(in) :: text_
      stat = 1
      msg = trim(path)//': '//text_
    end subroutine fail
  end subroutine read_config

  !> Check the variable names of group g against the allowed list.
  subroutine check_keys(text, g, allowed, label, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    character(len=*), intent(in) :: allowed(:), label
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer :: k
    character(len=:), allocatable :: list
    stat = 0
    msg = ''
    associate(grp => text%groups(g))
      do k = 1, grp%n_keys
        if (findloc(allowed, trim(grp%keys(k)), 1) == 0) then
          list = trim(allowed(1))
          block
            integer :: j
            do j = 2, size(allowed)
              list = list//', '//trim(allowed(j))
            end do
          end block
          stat = 1
          msg = label//': unknown variable "'//trim(grp%keys(k))//'" on line '// &
                itoa(grp%key_lines(k))//' (allowed: '//list//')'
          return
        end if
      end do
    end associate
  end subroutine check_keys

  !> Turn a failed namelist read into a message that names the line and its text.
  subroutine read_error(text, g, label, iomsg, chunk, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    character(len=*), intent(in) :: label, iomsg
    character(len=line_len), intent(in) :: chunk(:)
    character(len=:), allocatable, intent(out) :: msg
    integer :: bad
    bad = find_bad_line(chunk, trim(text%groups(g)%name))
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
  integer function find_bad_line(chunk, name) result(bad)
    character(len=line_len), intent(in) :: chunk(:)
    character(len=*), intent(in) :: name
    character(len=line_len), allocatable :: part(:)
    integer :: n, ios
    bad = 0
    do n = 1, size(chunk)
      allocate(part(n + 1))
      part(1:n) = chunk(1:n)
      part(n + 1) = '/'
      ios = try_read(part, name)
      deallocate(part)
      if (ios /= 0) then
        bad = n
        return
      end if
    end do
  end function find_bad_line

  !> Read a chunk into throw-away variables of the named group; returns iostat.
  integer function try_read(part, name) result(ios)
    character(len=line_len), intent(in) :: part(:)
    character(len=*), intent(in) :: name
    type(config_t) :: c
    type(bc_config_t) :: b
    type(load_config_t) :: l
    type(probe_config_t) :: p
    character(len=:), allocatable :: m
    select case (name)
    case ('run')
      call parse_run(part, c, ios, m)
    case ('geometry')
      call parse_geometry(part, c, ios, m)
    case ('material')
      call parse_material(part, c, ios, m)
    case ('damping')
      call parse_damping(part, c, ios, m)
    case ('bc')
      call parse_bc(part, b, ios, m)
    case ('load')
      call parse_load(part, l, ios, m)
    case ('probe')
      call parse_probe(part, p, ios, m)
    case ('static')
      call parse_static(part, c, ios, m)
    case ('initial')
      call parse_initial(part, c, ios, m)
    case default
      ios = 0
    end select
  end function try_read

  ! ------------------------------------------------------------------------------ &initial
  subroutine parse_initial(chunk, cfg, ios, iomsg)
    character(len=line_len), intent(in) :: chunk(:)
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: ios
    character(len=:), allocatable, intent(out) :: iomsg
    real(wp) :: velocity(2), angular_velocity, center(2)
    character(len=256) :: m
    namelist /initial/ velocity, angular_velocity, center
    velocity = cfg%initial%velocity; angular_velocity = cfg%initial%angular_velocity
    center = cfg%initial%center
    m = ''
    read(chunk, nml=initial, iostat=ios, iomsg=m)
    iomsg = trim(m)
    cfg%initial%velocity = velocity; cfg%initial%angular_velocity = angular_velocity
    cfg%initial%center = center
  end subroutine parse_initial

  subroutine read_initial(text, g, cfg, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=:), allocatable :: iomsg
    character(len=*), parameter :: label = '&initial'
    call check_keys(text, g, [character(len=16) :: 'velocity', 'angular_velocity', 'center'], &
                    label, stat, msg)
    if (stat /= 0) return
    call text%chunk(g, chunk)
    call parse_initial(chunk, cfg, stat, iomsg)
    if (stat /= 0) then
      call read_error(text, g, label, iomsg, chunk, msg)
      stat = 1
      return
    end if
    cfg%initial%given = .true.
    if (.not. all(ieee_is_finite([cfg%initial%velocity, cfg%initial%angular_velocity, &
                                  cfg%initial%center]))) then
      call bad(label, 'velocity, angular_velocity, center', '', 'must be finite numbers', &
               stat, msg)
    end if
  end subroutine read_initial

  ! ---------------------------------------------------------------------------------- &run
  subroutine parse_run(chunk, cfg, ios, iomsg)
    character(len=line_len), intent(in) :: chunk(:)
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: ios
    character(len=:), allocatable, intent(out) :: iomsg
    character(len=16) :: analysis, integrator
    real(wp) :: t_end, dt, dt_safety, output_interval, history_interval, progress_interval
    real(wp) :: energy_warn, energy_stop, checkpoint_interval
    integer :: check_interval
    character(len=path_len) :: output_file, checkpoint_file, restart
    logical :: overwrite, allow_unstable_dt
    character(len=256) :: m
    namelist /run/ analysis, integrator, t_end, dt, dt_safety, output_interval, &
      history_interval, progress_interval, output_file, overwrite, energy_warn, energy_stop, &
      check_interval, allow_unstable_dt, checkpoint_interval, checkpoint_file, restart
    analysis = cfg%run%analysis; integrator = cfg%run%integrator
    t_end = unset_real; dt = cfg%run%dt
    dt_safety = cfg%run%dt_safety; output_interval = cfg%run%output_interval
    history_interval = cfg%run%history_interval; progress_interval = cfg%run%progress_interval
    output_file = cfg%run%output_file; overwrite = cfg%run%overwrite
    energy_warn = cfg%run%energy_warn; energy_stop = cfg%run%energy_stop
    check_interval = cfg%run%check_interval; allow_unstable_dt = cfg%run%allow_unstable_dt
    checkpoint_interval = cfg%run%checkpoint_interval
    checkpoint_file = cfg%run%checkpoint_file; restart = cfg%run%restart
    m = ''
    read(chunk, nml=run, iostat=ios, iomsg=m)
    iomsg = trim(m)
    cfg%run%analysis = lower(analysis); cfg%run%integrator = lower(integrator)
    cfg%run%t_end = t_end; cfg%run%dt = dt
    cfg%run%dt_safety = dt_safety; cfg%run%output_interval = output_interval
    cfg%run%history_interval = history_interval; cfg%run%progress_interval = progress_interval
    cfg%run%output_file = output_file; cfg%run%overwrite = overwrite
    cfg%run%energy_warn = energy_warn; cfg%run%energy_stop = energy_stop
    cfg%run%check_interval = check_interval; cfg%run%allow_unstable_dt = allow_unstable_dt
    cfg%run%checkpoint_interval = checkpoint_interval
    cfg%run%checkpoint_file = checkpoint_file; cfg%run%restart = restart
  end subroutine parse_run

  subroutine read_run(text, g, cfg, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=:), allocatable :: iomsg
    character(len=*), parameter :: label = '&run'
    call check_keys(text, g, [character(len=20) :: 'analysis', 'integrator', 't_end', 'dt', &
      'dt_safety', 'output_interval', 'history_interval', 'progress_interval', 'output_file', &
      'overwrite', 'energy_warn', 'energy_stop', 'check_interval', 'allow_unstable_dt', &
      'checkpoint_interval', 'checkpoint_file', 'restart'], label, stat, msg)
    if (stat /= 0) return
    call text%chunk(g, chunk)
    call parse_run(chunk, cfg, stat, iomsg)
    if (stat /= 0) then
      call read_error(text, g, label, iomsg, chunk, msg)
      stat = 1
      return
    end if
    associate(r => cfg%run)
      if (r%analysis /= 'dynamic' .and. r%analysis /= 'static') then
        call bad(label, 'analysis', "'"//trim(r%analysis)//"'", &
                 "must be 'dynamic' or 'static'", stat, msg)
      else if (r%integrator /= 'rk4' .and. r%integrator /= 'verlet') then
        call bad(label, 'integrator', "'"//trim(r%integrator)//"'", &
                 "must be 'rk4' or 'verlet'", stat, msg)
      else if (r%analysis == 'static' .and. len(dynamic_only(text, g)) > 0) then
        call bad(label, dynamic_only(text, g), '', "applies only to analysis = 'dynamic'; "// &
                 "a static run takes its steps from &static (load_steps) and writes one "// &
                 "frame and one history sample per load step", stat, msg)
      else if (r%t_end == unset_real) then
        call bad(label, 't_end', '(not given)', 'is required: the end time in s', stat, msg)
      else if (.not. (r%t_end > 0.0_wp)) then
        call bad(label, 't_end', rtoa(r%t_end), 'must be > 0 [s]', stat, msg)
      else if (.not. (r%dt >= 0.0_wp)) then
        call bad(label, 'dt', rtoa(r%dt), 'must be >= 0 [s] (0: automatic)', stat, msg)
      else if (r%dt > r%t_end) then
        call bad(label, 'dt', rtoa(r%dt), 'must not exceed t_end = '//rtoa(r%t_end), stat, msg)
      else if (.not. (r%dt_safety > 0.0_wp .and. r%dt_safety <= 1.0_wp)) then
        call bad(label, 'dt_safety', rtoa(r%dt_safety), 'must be in (0, 1]', stat, msg)
      else if (.not. (r%output_interval >= 0.0_wp)) then
        call bad(label, 'output_interval', rtoa(r%output_interval), &
                 'must be >= 0 [s] (0: t_end/20)', stat, msg)
      else if (.not. (r%history_interval >= 0.0_wp)) then
        call bad(label, 'history_interval', rtoa(r%history_interval), &
                 'must be >= 0 [s] (0: t_end/1000)', stat, msg)
      else if (.not. (r%progress_interval > 0.0_wp)) then
        call bad(label, 'progress_interval', rtoa(r%progress_interval), &
                 'must be > 0 [s of wall time]', stat, msg)
      else if (.not. (r%energy_warn >= 0.0_wp)) then
        call bad(label, 'energy_warn', rtoa(r%energy_warn), 'must be >= 0 (0: off)', stat, msg)
      else if (.not. (r%energy_stop >= 0.0_wp)) then
        call bad(label, 'energy_stop', rtoa(r%energy_stop), 'must be >= 0 (0: off)', stat, msg)
      else if (r%energy_stop > 0.0_wp .and. r%energy_warn > r%energy_stop) then
        call bad(label, 'energy_warn', rtoa(r%energy_warn), 'must not exceed energy_stop = '// &
                 rtoa(r%energy_stop), stat, msg)
      else if (.not. (r%checkpoint_interval >= 0.0_wp)) then
        call bad(label, 'checkpoint_interval', rtoa(r%checkpoint_interval), &
                 'must be >= 0 [s] (0: checkpoints only on SIGTERM/SIGUSR1)', stat, msg)
      else if (r%check_interval < 1) then
        call bad(label, 'check_interval', itoa(r%check_interval), 'must be >= 1 [steps]', &
                 stat, msg)
      else if (len_trim(r%output_file) == 0) then
        call bad(label, 'output_file', "''", 'must name a file', stat, msg)
      end if
      if (len_trim(r%checkpoint_file) == 0) r%checkpoint_file = with_extension(r%output_file, &
                                                                          '.chk')
      if (r%output_interval == 0.0_wp) r%output_interval = r%t_end/20.0_wp
      if (r%history_interval == 0.0_wp) r%history_interval = r%t_end/1000.0_wp
    end associate
  end subroutine read_run

  !> path with the extension of its file name replaced by ext (or ext appended).
  pure function with_extension(path, ext) result(out)
    character(len=*), intent(in) :: path, ext
    character(len=:), allocatable :: out
    integer :: dot, slash
    slash = index(trim(path), '/', back=.true.)
    dot = index(trim(path), '.', back=.true.)
    if (dot > slash + 1) then
      out = path(1:dot - 1)//ext
    else
      out = trim(path)//ext
    end if
  end function with_extension

  !> The first variable of &run (group g) that only a dynamic run uses, or '' if none.
  function dynamic_only(text, g) result(name)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    character(len=:), allocatable :: name
    character(len=*), parameter :: vars(*) = [character(len=19) :: 'integrator', 'dt', &
      'dt_safety', 'output_interval', 'history_interval', 'energy_warn', 'energy_stop', &
      'check_interval', 'allow_unstable_dt', 'checkpoint_interval', 'checkpoint_file', 'restart']
    integer :: k
    name = ''
    associate(grp => text%groups(g))
      do k = 1, grp%n_keys
        if (findloc(vars, trim(grp%keys(k)), 1) > 0) then
          name = trim(grp%keys(k))
          return
        end if
      end do
    end associate
  end function dynamic_only

  ! ----------------------------------------------------------------------------- &geometry
  subroutine parse_geometry(chunk, cfg, ios, iomsg)
    character(len=line_len), intent(in) :: chunk(:)
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: ios
    character(len=:), allocatable, intent(out) :: iomsg
    real(wp) :: length, height, thickness, cell_size
    integer :: nx, ny
    character(len=8) :: plane, cell
    character(len=256) :: m
    namelist /geometry/ length, height, thickness, nx, ny, cell_size, plane, cell
    length = unset_real; height = unset_real; thickness = cfg%geometry%thickness
    nx = 0; ny = 0; cell_size = 0.0_wp; plane = cfg%geometry%plane; cell = cfg%geometry%cell
    m = ''
    read(chunk, nml=geometry, iostat=ios, iomsg=m)
    iomsg = trim(m)
    cfg%geometry%length = length; cfg%geometry%height = height
    cfg%geometry%thickness = thickness; cfg%geometry%nx = nx; cfg%geometry%ny = ny
    cfg%geometry%cell_size = cell_size; cfg%geometry%plane = lower(plane)
    cfg%geometry%cell = lower(cell)
  end subroutine parse_geometry

  subroutine read_geometry(text, g, cfg, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=:), allocatable :: iomsg
    character(len=*), parameter :: label = '&geometry'
    real(wp) :: nn
    call check_keys(text, g, [character(len=12) :: 'length', 'height', 'thickness', 'nx', 'ny', &
      'cell_size', 'plane', 'cell'], label, stat, msg)
    if (stat /= 0) return
    call text%chunk(g, chunk)
    call parse_geometry(chunk, cfg, stat, iomsg)
    if (stat /= 0) then
      call read_error(text, g, label, iomsg, chunk, msg)
      stat = 1
      return
    end if
    associate(o => cfg%geometry)
      if (o%length == unset_real) then
        call bad(label, 'length', '(not given)', 'is required [m]', stat, msg)
      else if (.not. (o%length > 0.0_wp)) then
        call bad(label, 'length', rtoa(o%length), 'must be > 0 [m]', stat, msg)
      else if (o%height == unset_real) then
        call bad(label, 'height', '(not given)', 'is required [m]', stat, msg)
      else if (.not. (o%height > 0.0_wp)) then
        call bad(label, 'height', rtoa(o%height), 'must be > 0 [m]', stat, msg)
      else if (.not. (o%thickness > 0.0_wp)) then
        call bad(label, 'thickness', rtoa(o%thickness), 'must be > 0 [m]', stat, msg)
      else if (o%plane /= 'stress' .and. o%plane /= 'strain') then
        call bad(label, 'plane', "'"//trim(o%plane)//"'", "must be 'stress' or 'strain'", &
                 stat, msg)
      else if (o%cell /= 'paper' .and. o%cell /= 'bending') then
        call bad(label, 'cell', "'"//trim(o%cell)//"'", "must be 'paper' or 'bending'", &
                 stat, msg)
      else if (o%cell_size /= 0.0_wp .and. (o%nx /= 0 .or. o%ny /= 0)) then
        call bad(label, 'cell_size', rtoa(o%cell_size), 'cannot be combined with nx, ny', &
                 stat, msg)
      else if (.not. (o%cell_size >= 0.0_wp)) then
        call bad(label, 'cell_size', rtoa(o%cell_size), 'must be > 0 [m]', stat, msg)
      else if (o%cell_size == 0.0_wp .and. o%nx < 1) then
        call bad(label, 'nx', itoa(o%nx), 'must be >= 1 (or give cell_size)', stat, msg)
      else if (o%cell_size == 0.0_wp .and. o%ny < 1) then
        call bad(label, 'ny', itoa(o%ny), 'must be >= 1 (or give cell_size)', stat, msg)
      end if
      if (stat /= 0) return
      if (o%cell_size > 0.0_wp) then
        o%nx = max(1, nint(o%length/o%cell_size))
        o%ny = max(1, nint(o%height/o%cell_size))
      end if
      nn = real(o%nx + 1, wp)*real(o%ny + 1, wp)
      if (nn > 2.0e9_wp) then
        call bad(label, 'nx*ny', itoa(o%nx)//'*'//itoa(o%ny), &
                 'gives more than 2e9 nodes', stat, msg)
      end if
    end associate
  end subroutine read_geometry

  ! ----------------------------------------------------------------------------- &material
  subroutine parse_material(chunk, cfg, ios, iomsg)
    character(len=line_len), intent(in) :: chunk(:)
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: ios
    character(len=:), allocatable, intent(out) :: iomsg
    real(wp) :: e, nu, density, tensile_strength, compressive_strength, shear_strength
    logical :: nonlinear
    integer :: history_depth
    character(len=256) :: m
    namelist /material/ e, nu, density, nonlinear, tensile_strength, compressive_strength, &
      shear_strength, history_depth
    e = unset_real; nu = unset_real; density = unset_real
    nonlinear = cfg%material%nonlinear; history_depth = cfg%material%history_depth
    tensile_strength = unset_real; compressive_strength = unset_real
    shear_strength = unset_real
    m = ''
    read(chunk, nml=material, iostat=ios, iomsg=m)
    iomsg = trim(m)
    cfg%material%young = e; cfg%material%poisson = nu; cfg%material%density = density
    cfg%material%nonlinear = nonlinear; cfg%material%history_depth = history_depth
    cfg%material%tensile_strength = tensile_strength
    cfg%material%compressive_strength = compressive_strength
    cfg%material%shear_strength = shear_strength
  end subroutine parse_material

  subroutine read_material(text, g, cfg, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=:), allocatable :: iomsg
    character(len=*), parameter :: label = '&material'
    call check_keys(text, g, [character(len=20) :: 'e', 'nu', 'density', 'nonlinear', &
      'tensile_strength', 'compressive_strength', 'shear_strength', 'history_depth'], label, &
      stat, msg)
    if (stat /= 0) return
    call text%chunk(g, chunk)
    call parse_material(chunk, cfg, stat, iomsg)
    if (stat /= 0) then
      call read_error(text, g, label, iomsg, chunk, msg)
      stat = 1
      return
    end if
    associate(m => cfg%material)
      if (m%young == unset_real) then
        call bad(label, 'E', '(not given)', "is required: Young's modulus [Pa]", stat, msg)
      else if (.not. (m%young > 0.0_wp)) then
        call bad(label, 'E', rtoa(m%young), 'must be > 0 [Pa]', stat, msg)
      else if (m%poisson == unset_real) then
        call bad(label, 'nu', '(not given)', "is required: Poisson's ratio", stat, msg)
      else if (.not. (m%poisson > -1.0_wp .and. m%poisson < 0.5_wp)) then
        call bad(label, 'nu', rtoa(m%poisson), 'must be in (-1, 0.5)', stat, msg)
      else if (m%density == unset_real) then
        call bad(label, 'density', '(not given)', 'is required [kg/m^3]', stat, msg)
      else if (.not. (m%density > 0.0_wp)) then
        call bad(label, 'density', rtoa(m%density), 'must be > 0 [kg/m^3]', stat, msg)
      else if (m%nonlinear) then
        call check_strength('tensile_strength', m%tensile_strength)
        if (stat == 0) call check_strength('compressive_strength', m%compressive_strength)
        if (stat == 0) call check_strength('shear_strength', m%shear_strength)
        if (stat == 0 .and. m%history_depth < 2) call bad(label, 'history_depth', &
          itoa(m%history_depth), 'must be >= 2 (reversal points kept per spring)', stat, msg)
      else
        ! strengths without nonlinear = .true. would be silently ignored
        if (m%tensile_strength /= unset_real) then
          call bad(label, 'tensile_strength', rtoa(m%tensile_strength), &
                   'is used only with nonlinear = .true.', stat, msg)
        else if (m%compressive_strength /= unset_real) then
          call bad(label, 'compressive_strength', rtoa(m%compressive_strength), &
                   'is used only with nonlinear = .true.', stat, msg)
        else if (m%shear_strength /= unset_real) then
          call bad(label, 'shear_strength', rtoa(m%shear_strength), &
                   'is used only with nonlinear = .true.', stat, msg)
        end if
      end if
    end associate
  contains
    subroutine check_strength(name, value)
      character(len=*), intent(in) :: name
      real(wp), intent(in) :: value
      if (value == unset_real) then
        call bad(label, name, '(not given)', 'is required with nonlinear = .true. [Pa]', stat, msg)
      else if (.not. (value > 0.0_wp)) then
        call bad(label, name, rtoa(value), 'must be > 0 [Pa]', stat, msg)
      end if
    end subroutine check_strength
  end subroutine read_material

  ! ------------------------------------------------------------------------------ &damping
  subroutine parse_damping(chunk, cfg, ios, iomsg)
    character(len=line_len), intent(in) :: chunk(:)
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: ios
    character(len=:), allocatable, intent(out) :: iomsg
    character(len=12) :: kind
    real(wp) :: ratio, frequency, alpha, beta
    character(len=256) :: m
    real(wp) :: cap_frequency
    namelist /damping/ kind, ratio, frequency, alpha, beta, cap_frequency
    kind = 'none'; ratio = unset_real; frequency = unset_real
    alpha = unset_real; beta = unset_real; cap_frequency = unset_real
    m = ''
    read(chunk, nml=damping, iostat=ios, iomsg=m)
    iomsg = trim(m)
    cfg%damping%kind = lower(kind); cfg%damping%ratio = ratio
    cfg%damping%frequency = frequency; cfg%damping%alpha = alpha; cfg%damping%beta = beta
    cfg%damping%cap_frequency = cap_frequency
  end subroutine parse_damping

  subroutine read_damping(text, g, cfg, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=:), allocatable :: iomsg
    character(len=*), parameter :: label = '&damping'
    real(wp) :: omega
    logical :: by_ratio, by_coeff
    call check_keys(text, g, [character(len=13) :: 'kind', 'ratio', 'frequency', 'alpha', &
      'beta', 'cap_frequency'], label, stat, msg)
    if (stat /= 0) return
    call text%chunk(g, chunk)
    call parse_damping(chunk, cfg, stat, iomsg)
    if (stat /= 0) then
      call read_error(text, g, label, iomsg, chunk, msg)
      stat = 1
      return
    end if
    associate(d => cfg%damping)
      by_ratio = d%ratio /= unset_real .or. d%frequency /= unset_real
      by_coeff = d%alpha /= unset_real .or. d%beta /= unset_real
      select case (trim(d%kind))
      case ('none')
        if (by_ratio .or. by_coeff) call bad(label, 'kind', "'none'", &
          'takes no ratio, frequency, alpha or beta', stat, msg)
      case ('mass', 'stiffness', 'rayleigh', 'capped')
        if (trim(d%kind) /= 'capped' .and. d%cap_frequency /= unset_real) then
          call bad(label, 'cap_frequency', rtoa(d%cap_frequency), &
                   "needs kind = 'capped'", stat, msg)
        else if (trim(d%kind) == 'capped' .and. d%cap_frequency == unset_real) then
          call bad(label, 'cap_frequency', '(not given)', &
                   "is required for kind = 'capped' [Hz]", stat, msg)
        else if (trim(d%kind) == 'capped' .and. .not. (d%cap_frequency > 0.0_wp)) then
          call bad(label, 'cap_frequency', rtoa(d%cap_frequency), 'must be > 0 [Hz]', &
                   stat, msg)
        else if (by_coeff .and. trim(d%kind) /= 'rayleigh') then
          call bad(label, 'kind', "'"//trim(d%kind)//"'", &
                   "is given by ratio and frequency; alpha, beta need kind = 'rayleigh'", stat, msg)
        else if (by_coeff .and. by_ratio) then
          call bad(label, 'alpha', rtoa(d%alpha), &
                   'give either ratio and frequency, or alpha and beta, not both', stat, msg)
        else if (by_coeff) then
          if (d%alpha == unset_real) d%alpha = 0.0_wp
          if (d%beta == unset_real) d%beta = 0.0_wp
          if (.not. (d%alpha >= 0.0_wp)) then
            call bad(label, 'alpha', rtoa(d%alpha), 'must be >= 0 [1/s]', stat, msg)
          else if (.not. (d%beta >= 0.0_wp)) then
            call bad(label, 'beta', rtoa(d%beta), 'must be >= 0 [s]', stat, msg)
          end if
        else if (d%ratio == unset_real) then
          call bad(label, 'ratio', '(not given)', 'is required for kind = '''// &
                   trim(d%kind)//'''', stat, msg)
        else if (.not. (d%ratio >= 0.0_wp .and. d%ratio < 1.0_wp)) then
          call bad(label, 'ratio', rtoa(d%ratio), 'must be in [0, 1)', stat, msg)
        else if (d%frequency == unset_real) then
          call bad(label, 'frequency', '(not given)', 'is required with ratio [Hz]', stat, msg)
        else if (.not. (d%frequency > 0.0_wp)) then
          call bad(label, 'frequency', rtoa(d%frequency), 'must be > 0 [Hz]', stat, msg)
        else
          omega = 2.0_wp*3.141592653589793_wp*d%frequency
          select case (trim(d%kind))
          case ('mass')
            d%alpha = 2.0_wp*d%ratio*omega; d%beta = 0.0_wp
          case ('stiffness')
            d%alpha = 0.0_wp; d%beta = 2.0_wp*d%ratio/omega
          case ('rayleigh')
            d%alpha = d%ratio*omega; d%beta = d%ratio/omega
          case ('capped')
            ! beta follows from ratio, frequency and cap_frequency in the model
            d%alpha = 0.0_wp; d%beta = 0.0_wp
          end select
        end if
      case default
        call bad(label, 'kind', "'"//trim(d%kind)//"'", &
                 "must be 'none', 'mass', 'stiffness', 'rayleigh' or 'capped'", stat, msg)
      end select
      if (d%kind == 'none') then
        d%alpha = 0.0_wp; d%beta = 0.0_wp
      end if
      if (d%ratio == unset_real) d%ratio = 0.0_wp
      if (d%frequency == unset_real) d%frequency = 0.0_wp
      if (d%cap_frequency == unset_real) d%cap_frequency = 0.0_wp
    end associate
  end subroutine read_damping

  ! ------------------------------------------------------------------------------- &static
  subroutine parse_static(chunk, cfg, ios, iomsg)
    character(len=line_len), intent(in) :: chunk(:)
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: ios
    character(len=:), allocatable, intent(out) :: iomsg
    integer :: load_steps, max_iterations
    real(wp) :: tolerance
    character(len=12) :: method, mass
    character(len=256) :: m
    namelist /static/ load_steps, tolerance, max_iterations, method, mass
    load_steps = cfg%static%load_steps; tolerance = cfg%static%tolerance
    max_iterations = cfg%static%max_iterations; method = cfg%static%method
    mass = cfg%static%mass
    m = ''
    read(chunk, nml=static, iostat=ios, iomsg=m)
    iomsg = trim(m)
    cfg%static%load_steps = load_steps; cfg%static%tolerance = tolerance
    cfg%static%max_iterations = max_iterations; cfg%static%method = lower(method)
    cfg%static%mass = lower(mass)
  end subroutine parse_static

  subroutine read_static(text, g, cfg, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=:), allocatable :: iomsg
    character(len=*), parameter :: label = '&static'
    call check_keys(text, g, [character(len=14) :: 'load_steps', 'tolerance', &
      'max_iterations', 'method', 'mass'], label, stat, msg)
    if (stat /= 0) return
    call text%chunk(g, chunk)
    call parse_static(chunk, cfg, stat, iomsg)
    if (stat /= 0) then
      call read_error(text, g, label, iomsg, chunk, msg)
      stat = 1
      return
    end if
    cfg%static%given = .true.
    associate(s => cfg%static)
      if (s%load_steps < 1) then
        call bad(label, 'load_steps', itoa(s%load_steps), 'must be >= 1', stat, msg)
      else if (.not. (s%tolerance > 0.0_wp .and. s%tolerance < 1.0_wp)) then
        call bad(label, 'tolerance', rtoa(s%tolerance), &
                 'must be in (0, 1): the relative residual of each load step', stat, msg)
      else if (s%max_iterations < 1) then
        call bad(label, 'max_iterations', itoa(s%max_iterations), 'must be >= 1', stat, msg)
      else if (s%method /= 'kinetic' .and. s%method /= 'viscous') then
        call bad(label, 'method', "'"//trim(s%method)//"'", "must be 'kinetic' or 'viscous'", &
                 stat, msg)
      else if (s%mass /= 'lumped' .and. s%mass /= 'gershgorin') then
        call bad(label, 'mass', "'"//trim(s%mass)//"'", "must be 'lumped' or 'gershgorin'", &
                 stat, msg)
      end if
    end associate
  end subroutine read_static

  ! ----------------------------------------------------------------------------------- &bc
  subroutine parse_bc(chunk, b, ios, iomsg)
    character(len=line_len), intent(in) :: chunk(:)
    type(bc_config_t), intent(inout) :: b
    integer, intent(out) :: ios
    character(len=:), allocatable, intent(out) :: iomsg
    character(len=name_len) :: name
    character(len=8) :: where, kind, dofs, time_function
    real(wp) :: box(4), point(2), velocity(2), t_start, t_ramp, t_release
    character(len=256) :: m
    namelist /bc/ name, where, box, point, kind, dofs, velocity, time_function, t_start, &
      t_ramp, t_release
    name = ''; where = ''; box = unset_real; point = unset_real; kind = 'fix'; dofs = 'xy'
    velocity = 0.0_wp; time_function = 'constant'; t_start = 0.0_wp; t_ramp = 0.0_wp
    t_release = huge(1.0_wp)
    m = ''
    read(chunk, nml=bc, iostat=ios, iomsg=m)
    iomsg = trim(m)
    b%name = name; b%set%where = lower(where); b%set%box = box; b%set%point = point
    b%kind = lower(kind); b%velocity = velocity
    b%dof(1) = index(lower(dofs), 'x') > 0
    b%dof(2) = index(lower(dofs), 'y') > 0
    if (len_trim(dofs) == 0 .or. verify(trim(lower(dofs)), 'xy') /= 0) b%dof = .false.
    b%tf%kind = lower(time_function); b%tf%t_start = t_start; b%tf%t_ramp = t_ramp
    b%t_release = t_release
  end subroutine parse_bc

  subroutine read_bc(text, g, ib, b, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g, ib
    type(bc_config_t), intent(inout) :: b
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=:), allocatable :: iomsg, label
    label = '&bc #'//itoa(ib)//' (line '//itoa(text%groups(g)%first_line)//')'
    call check_keys(text, g, [character(len=14) :: 'name', 'where', 'box', 'point', 'kind', &
      'dofs', 'velocity', 'time_function', 't_start', 't_ramp', 't_release'], label, stat, msg)
    if (stat /= 0) return
    call text%chunk(g, chunk)
    call parse_bc(chunk, b, stat, iomsg)
    if (stat /= 0) then
      call read_error(text, g, label, iomsg, chunk, msg)
      stat = 1
      return
    end if
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

  ! --------------------------------------------------------------------------------- &load
  subroutine parse_load(chunk, l, ios, iomsg)
    character(len=line_len), intent(in) :: chunk(:)
    type(load_config_t), intent(inout) :: l
    integer, intent(out) :: ios
    character(len=:), allocatable, intent(out) :: iomsg
    character(len=name_len) :: name
    character(len=8) :: where, kind, time_function
    real(wp) :: box(4), point(2), force(2), traction(2), accel(2), t_start, t_ramp
    character(len=256) :: m
    namelist /load/ name, kind, where, box, point, force, traction, accel, time_function, &
      t_start, t_ramp
    name = ''; kind = 'nodal'; where = ''; box = unset_real; point = unset_real
    force = unset_real; traction = unset_real; accel = unset_real
    time_function = 'constant'; t_start = 0.0_wp; t_ramp = 0.0_wp
    m = ''
    read(chunk, nml=load, iostat=ios, iomsg=m)
    iomsg = trim(m)
    l%name = name; l%kind = lower(kind); l%set%where = lower(where); l%set%box = box
    l%set%point = point
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
      'force', 'traction', 'accel', 'time_function', 't_start', 't_ramp'], label, stat, msg)
    if (stat /= 0) return
    call text%chunk(g, chunk)
    call parse_load(chunk, l, stat, iomsg)
    if (stat /= 0) then
      call read_error(text, g, label, iomsg, chunk, msg)
      stat = 1
      return
    end if
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
      call read_error(text, g, label, iomsg, chunk, msg)
      stat = 1
      return
    end if
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

  ! ------------------------------------------------------------------------------- checks
  !> Validate a node-set description (named edge, box, point or all).
  subroutine check_set(s, label, edge_only, stat, msg)
    type(node_set_spec_t), intent(inout) :: s
    character(len=*), intent(in) :: label
    logical, intent(in) :: edge_only
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    stat = 0
    msg = ''
    select case (trim(s%where))
    case ('left', 'right', 'bottom', 'top')
      continue
    case ('box')
      if (edge_only) then
        call bad(label, 'where', "'box'", "an edge load needs 'left', 'right', 'bottom' or "// &
                 "'top'", stat, msg)
      else if (any(s%box == unset_real)) then
        call bad(label, 'box', '(not given)', "is required with where = 'box': "// &
                 'xmin, xmax, ymin, ymax [m]', stat, msg)
      else if (s%box(1) > s%box(2) .or. s%box(3) > s%box(4)) then
        call bad(label, 'box', rtoa(s%box(1))//', '//rtoa(s%box(2))//', '//rtoa(s%box(3))// &
                 ', '//rtoa(s%box(4)), 'needs xmin <= xmax and ymin <= ymax', stat, msg)
      end if
    case ('point')
      if (edge_only) then
        call bad(label, 'where', "'point'", "an edge load needs 'left', 'right', 'bottom' or "// &
                 "'top'", stat, msg)
      else if (any(s%point == unset_real)) then
        call bad(label, 'point', '(not given)', "is required with where = 'point': x, y [m]", &
                 stat, msg)
      end if
    case ('all')
      if (edge_only) call bad(label, 'where', "'all'", &
        "an edge load needs 'left', 'right', 'bottom' or 'top'", stat, msg)
    case ('')
      call bad(label, 'where', "''", "is required: 'left', 'right', 'bottom', 'top', 'box', "// &
               "'point' or 'all'", stat, msg)
    case default
      call bad(label, 'where', "'"//trim(s%where)//"'", "must be 'left', 'right', 'bottom', "// &
               "'top', 'box', 'point' or 'all'", stat, msg)
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

  !> Checks that involve several groups: &static only with a static analysis, probes inside
  !> the body, unique probe names.
  subroutine check_cross(cfg, stat, msg)
    type(config_t), intent(in) :: cfg
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer :: k, j
    real(wp) :: tol
    stat = 0
    msg = ''
    if (cfg%static%given .and. cfg%run%analysis /= 'static') then
      stat = 1
      msg = "&static is only for analysis = 'static', but &run has analysis = '"// &
            trim(cfg%run%analysis)//"'; remove &static or set analysis = 'static' in &run"
      return
    end if
    if (len_trim(cfg%run%restart) > 0 .and. cfg%run%analysis == 'static') then
      call bad('&run', 'restart', "'"//trim(cfg%run%restart)//"'", "is only for analysis = "// &
               "'dynamic' (a static run is not checkpointed yet)", stat, msg)
      return
    end if
    if (cfg%initial%given .and. cfg%run%analysis == 'static') then
      stat = 1
      msg = "&initial is only for analysis = 'dynamic' (a static run starts at rest)"
      return
    end if
    if (cfg%run%analysis == 'static' .and. any(cfg%bcs(:)%t_release < huge(1.0_wp))) then
      k = findloc(cfg%bcs(:)%t_release < huge(1.0_wp), .true., 1)
      call bad('&bc #'//itoa(k), 't_release', rtoa(cfg%bcs(k)%t_release), "is only for "// &
               "analysis = 'dynamic'", stat, msg)
      return
    end if
    if (cfg%material%nonlinear .and. cfg%geometry%cell /= 'paper') then
      call bad('&geometry', 'cell', "'"//trim(cfg%geometry%cell)//"'", "cannot be used with "// &
               "nonlinear springs (&material nonlinear = .true.): use cell = 'paper'", stat, msg)
      return
    end if
    tol = 1.0e-9_wp*max(cfg%geometry%length, cfg%geometry%height)
    do k = 1, size(cfg%probes)
      associate(p => cfg%probes(k))
        if (p%x < -tol .or. p%x > cfg%geometry%length + tol .or. &
            p%y < -tol .or. p%y > cfg%geometry%height + tol) then
          call bad('&probe #'//itoa(k), 'x, y', rtoa(p%x)//', '//rtoa(p%y), &
                   'is outside the body [0, '//rtoa(cfg%geometry%length)//'] x [0, '// &
                   rtoa(cfg%geometry%height)//']', stat, msg)
          return
        end if
        do j = 1, k - 1
          if (cfg%probes(j)%name == p%name) then
            call bad('&probe #'//itoa(k), 'name', "'"//trim(p%name)//"'", &
                     'is already used by &probe #'//itoa(j), stat, msg)
            return
          end if
        end do
      end associate
    end do
  end subroutine check_cross

  !> Rank 0 checks the output path (folder exists; no file unless overwrite) for all ranks.
  subroutine check_files(cfg, comm, stat, msg)
    type(config_t), intent(in) :: cfg
    type(MPI_Comm), intent(in) :: comm
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer :: rank, code, k
    logical :: there
    character(len=:), allocatable :: path, folder
    call MPI_Comm_rank(comm, rank)
    path = trim(cfg%run%output_file)
    code = 0
    if (rank == 0) then
      k = index(path, '/', back=.true.)
      if (k > 1) then
        folder = path(1:k - 1)
        inquire(file=folder//'/.', exist=there)
        if (.not. there) code = 1
      end if
      if (code == 0) then
        inquire(file=path, exist=there)
        if (len_trim(cfg%run%restart) > 0) then
          ! a restart appends to the output of the interrupted run
          if (.not. there) code = 3
          inquire(file=trim(cfg%run%restart), exist=there)
          if (code == 0 .and. .not. there) code = 4
        else if (there .and. .not. cfg%run%overwrite) then
          code = 2
        end if
      end if
    end if
    call MPI_Bcast(code, 1, MPI_INTEGER, 0, comm)
    stat = code
    msg = ''
    if (code == 1) then
      msg = trim(cfg%input_file)//": &run: output_file = '"//path// &
            "': its folder does not exist"
    else if (code == 2) then
      msg = trim(cfg%input_file)//": &run: output_file = '"//path// &
            "' exists; set overwrite = .true. to replace it"
    else if (code == 3) then
      msg = trim(cfg%input_file)//": &run: output_file = '"//path//"' does not exist: a "// &
            "restart appends to the output of the run it continues"
    else if (code == 4) then
      msg = trim(cfg%input_file)//": &run: restart = '"//trim(cfg%run%restart)// &
            "': no such file"
    end if
  end subroutine check_files

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
end module iem_input
