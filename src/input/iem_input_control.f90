!> Readers of the groups that control a run: &run, &static and &initial.
module iem_input_control
  use iem_kinds, only: wp
  use iem_constants, only: unset_real
  use iem_strings, only: rtoa, lower
  use iem_config, only: config_t, run_config_t, path_len
  use iem_namelist_text, only: nml_text_t, line_len
  use iem_input_checks, only: bad
  use iem_input_table, only: key_t, key, read_group, check_literals, check_values
  implicit none
  private
  public :: read_run, read_static, read_initial

contains

  ! ---------------------------------------------------------------------------------- &run
  subroutine parse_run(chunk, cfg, ios, iomsg)
    character(len=line_len), intent(in) :: chunk(:)
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: ios
    character(len=256), intent(out) :: iomsg
    character(len=16) :: analysis, integrator
    real(wp) :: t_end, dt, dt_safety, output_interval, history_interval, progress_interval
    real(wp) :: energy_warn, energy_stop, checkpoint_interval
    integer :: check_interval, repartition_step, balance_interval
    real(wp) :: balance_tolerance
    character(len=path_len) :: output_file, checkpoint_file, restart
    logical :: overwrite, allow_unstable_dt
    namelist /run/ analysis, integrator, t_end, dt, dt_safety, output_interval, &
      history_interval, progress_interval, output_file, overwrite, energy_warn, energy_stop, &
      check_interval, allow_unstable_dt, checkpoint_interval, checkpoint_file, restart, &
      repartition_step, balance_interval, balance_tolerance
    analysis = cfg%run%analysis; integrator = cfg%run%integrator
    t_end = unset_real; dt = cfg%run%dt
    dt_safety = cfg%run%dt_safety; output_interval = cfg%run%output_interval
    history_interval = cfg%run%history_interval; progress_interval = cfg%run%progress_interval
    output_file = cfg%run%output_file; overwrite = cfg%run%overwrite
    energy_warn = cfg%run%energy_warn; energy_stop = cfg%run%energy_stop
    check_interval = cfg%run%check_interval; allow_unstable_dt = cfg%run%allow_unstable_dt
    repartition_step = cfg%run%repartition_step
    balance_interval = cfg%run%balance_interval; balance_tolerance = cfg%run%balance_tolerance
    checkpoint_interval = cfg%run%checkpoint_interval
    checkpoint_file = cfg%run%checkpoint_file; restart = cfg%run%restart
    iomsg = ''
    read(chunk, nml=run, iostat=ios, iomsg=iomsg)
    cfg%run%analysis = lower(analysis); cfg%run%integrator = lower(integrator)
    cfg%run%t_end = t_end; cfg%run%dt = dt
    cfg%run%dt_safety = dt_safety; cfg%run%output_interval = output_interval
    cfg%run%history_interval = history_interval; cfg%run%progress_interval = progress_interval
    cfg%run%output_file = output_file; cfg%run%overwrite = overwrite
    cfg%run%energy_warn = energy_warn; cfg%run%energy_stop = energy_stop
    cfg%run%check_interval = check_interval; cfg%run%allow_unstable_dt = allow_unstable_dt
    cfg%run%repartition_step = repartition_step
    cfg%run%balance_interval = balance_interval; cfg%run%balance_tolerance = balance_tolerance
    cfg%run%checkpoint_interval = checkpoint_interval
    cfg%run%checkpoint_file = checkpoint_file; cfg%run%restart = restart
  end subroutine parse_run

  !> The table of &run's variables, kept in r.
  function run_keys(r) result(keys)
    type(run_config_t), intent(in), target :: r
    type(key_t) :: keys(20)
    keys = [key('analysis', r%analysis, allowed='dynamic static'), &
      key('integrator', r%integrator, allowed='rk4 verlet'), &
      key('t_end', r%t_end, need=': the end time in s', range='> 0', unit=' [s]'), &
      key('dt', r%dt, range='>= 0', unit=' [s] (0: automatic)'), &
      key('dt_safety', r%dt_safety, range='(0, 1]'), &
      key('output_interval', r%output_interval, range='>= 0', unit=' [s] (0: t_end/20)'), &
      key('history_interval', r%history_interval, range='>= 0', unit=' [s] (0: t_end/1000)'), &
      key('progress_interval', r%progress_interval, range='> 0', unit=' [s of wall time]'), &
      key('output_file', r%output_file), key('overwrite', r%overwrite), &
      key('energy_warn', r%energy_warn, range='>= 0', unit=' (0: off)'), &
      key('energy_stop', r%energy_stop, range='>= 0', unit=' (0: off)'), &
      key('check_interval', r%check_interval, range='>= 1', unit=' [steps]'), &
      key('allow_unstable_dt', r%allow_unstable_dt), &
      key('checkpoint_interval', r%checkpoint_interval, range='>= 0', &
          unit=' [s] (0: checkpoints only on SIGTERM/SIGUSR1)'), &
      key('checkpoint_file', r%checkpoint_file), key('restart', r%restart), &
      key('repartition_step', r%repartition_step, range='>= 0', unit=' [steps] (0: never)'), &
      key('balance_interval', r%balance_interval, range='>= 0', unit=' [steps] (0: never)'), &
      key('balance_tolerance', r%balance_tolerance, range='>= 0', unit=' (a fraction)')]
  end function run_keys

  !> Check, parse and validate group g (&run) of the input into the configuration.
  subroutine read_run(text, g, cfg, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    type(config_t), intent(inout), target :: cfg
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=256) :: iomsg
    character(len=*), parameter :: label = '&run'
    type(key_t) :: keys(20)
    keys = run_keys(cfg%run)
    call read_group(text, g, keys, label, try_run, chunk, stat, msg)
    if (stat /= 0) return
    call parse_run(chunk, cfg, stat, iomsg)
    call check_literals(text, g, keys, label, stat, msg)
    if (stat == 0) call check_values(keys, 'analysis integrator', label, stat, msg)
    if (stat /= 0) return
    associate(r => cfg%run)
      if (r%analysis == 'static' .and. len(dynamic_only(text, g)) > 0) then
        call bad(label, dynamic_only(text, g), '', "applies only to analysis = 'dynamic'; "// &
                 "a static run takes its steps from &static (load_steps) and writes one "// &
                 "frame and one history sample per load step", stat, msg)
      else
        call check_values(keys, 't_end dt', label, stat, msg)
      end if
      if (stat /= 0) return
      if (r%dt > r%t_end) then
        call bad(label, 'dt', rtoa(r%dt), 'must not exceed t_end = '//rtoa(r%t_end), stat, msg)
      else
        call check_values(keys, 'dt_safety output_interval history_interval '// &
                          'progress_interval energy_warn energy_stop', label, stat, msg)
      end if
      if (stat /= 0) return
      if (r%energy_stop > 0.0_wp .and. r%energy_warn > r%energy_stop) then
        call bad(label, 'energy_warn', rtoa(r%energy_warn), 'must not exceed energy_stop = '// &
                 rtoa(r%energy_stop), stat, msg)
      else
        call check_values(keys, 'checkpoint_interval check_interval repartition_step '// &
                          'balance_interval balance_tolerance', label, stat, msg)
      end if
      if (stat /= 0) return
      if (len_trim(r%output_file) == 0) then
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
      'check_interval', 'allow_unstable_dt', 'checkpoint_interval', 'checkpoint_file', 'restart', &
      'repartition_step', 'balance_interval', 'balance_tolerance']
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

  integer function try_run(part, iomsg) result(ios)
    character(len=line_len), intent(in) :: part(:)
    character(len=256), intent(out) :: iomsg
    type(config_t) :: c
    call parse_run(part, c, ios, iomsg)
  end function try_run

  ! ------------------------------------------------------------------------------- &static
  subroutine parse_static(chunk, cfg, ios, iomsg)
    character(len=line_len), intent(in) :: chunk(:)
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: ios
    character(len=256), intent(out) :: iomsg
    integer :: load_steps, max_iterations
    real(wp) :: tolerance
    character(len=12) :: method, mass
    namelist /static/ load_steps, tolerance, max_iterations, method, mass
    load_steps = cfg%static%load_steps; tolerance = cfg%static%tolerance
    max_iterations = cfg%static%max_iterations; method = cfg%static%method
    mass = cfg%static%mass
    iomsg = ''
    read(chunk, nml=static, iostat=ios, iomsg=iomsg)
    cfg%static%load_steps = load_steps; cfg%static%tolerance = tolerance
    cfg%static%max_iterations = max_iterations; cfg%static%method = lower(method)
    cfg%static%mass = lower(mass)
  end subroutine parse_static

  !> Check, parse and validate group g (&static) of the input into the configuration.
  subroutine read_static(text, g, cfg, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    type(config_t), intent(inout), target :: cfg
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=256) :: iomsg
    character(len=*), parameter :: label = '&static'
    type(key_t) :: keys(5)
    associate(s => cfg%static)
      keys = [key('load_steps', s%load_steps, range='>= 1'), &
        key('tolerance', s%tolerance, range='(0, 1)', &
            unit=': the relative residual of each load step'), &
        key('max_iterations', s%max_iterations, range='>= 1'), &
        key('method', s%method, allowed='kinetic viscous'), &
        key('mass', s%mass, allowed='lumped gershgorin')]
    end associate
    call read_group(text, g, keys, label, try_static, chunk, stat, msg)
    if (stat /= 0) return
    call parse_static(chunk, cfg, stat, iomsg)
    call check_literals(text, g, keys, label, stat, msg)
    if (stat /= 0) return
    cfg%static%given = .true.
    call check_values(keys, 'load_steps tolerance max_iterations method mass', label, stat, msg)
  end subroutine read_static

  integer function try_static(part, iomsg) result(ios)
    character(len=line_len), intent(in) :: part(:)
    character(len=256), intent(out) :: iomsg
    type(config_t) :: c
    call parse_static(part, c, ios, iomsg)
  end function try_static

  ! ------------------------------------------------------------------------------ &initial
  subroutine parse_initial(chunk, cfg, ios, iomsg)
    character(len=line_len), intent(in) :: chunk(:)
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: ios
    character(len=256), intent(out) :: iomsg
    real(wp) :: velocity(2), angular_velocity, center(2)
    namelist /initial/ velocity, angular_velocity, center
    velocity = cfg%initial%velocity; angular_velocity = cfg%initial%angular_velocity
    center = cfg%initial%center
    iomsg = ''
    read(chunk, nml=initial, iostat=ios, iomsg=iomsg)
    cfg%initial%velocity = velocity; cfg%initial%angular_velocity = angular_velocity
    cfg%initial%center = center
  end subroutine parse_initial

  !> Check, parse and validate group g (&initial) of the input into the configuration.
  subroutine read_initial(text, g, cfg, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    type(config_t), intent(inout), target :: cfg
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=256) :: iomsg
    character(len=*), parameter :: label = '&initial'
    type(key_t) :: keys(3)
    keys = [key('velocity', cfg%initial%velocity), &
      key('angular_velocity', cfg%initial%angular_velocity), key('center', cfg%initial%center)]
    call read_group(text, g, keys, label, try_initial, chunk, stat, msg)
    if (stat /= 0) return
    call parse_initial(chunk, cfg, stat, iomsg)
    call check_literals(text, g, keys, label, stat, msg)
    if (stat /= 0) return
    cfg%initial%given = .true.
  end subroutine read_initial

  integer function try_initial(part, iomsg) result(ios)
    character(len=line_len), intent(in) :: part(:)
    character(len=256), intent(out) :: iomsg
    type(config_t) :: c
    call parse_initial(part, c, ios, iomsg)
  end function try_initial

end module iem_input_control
