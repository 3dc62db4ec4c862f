!> Readers of the groups that control a run: &run, &static and &initial.
module iem_input_control
  use iem_kinds, only: wp, i8
  use iem_constants, only: unset_real
  use iem_strings, only: itoa, rtoa, lower
  use iem_config, only: config_t, path_len
  use iem_namelist_text, only: nml_text_t, line_len
  use iem_input_checks, only: bad, check_keys, read_error, check_reals, check_logicals, &
                              check_strings
  implicit none
  private
  public :: read_run, read_static, read_initial

contains

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
    integer(i8) :: repartition_step
    character(len=path_len) :: output_file, checkpoint_file, restart
    logical :: overwrite, allow_unstable_dt
    character(len=256) :: m
    namelist /run/ analysis, integrator, t_end, dt, dt_safety, output_interval, &
      history_interval, progress_interval, output_file, overwrite, energy_warn, energy_stop, &
      check_interval, allow_unstable_dt, checkpoint_interval, checkpoint_file, restart, &
      repartition_step
    analysis = cfg%run%analysis; integrator = cfg%run%integrator
    t_end = unset_real; dt = cfg%run%dt
    dt_safety = cfg%run%dt_safety; output_interval = cfg%run%output_interval
    history_interval = cfg%run%history_interval; progress_interval = cfg%run%progress_interval
    output_file = cfg%run%output_file; overwrite = cfg%run%overwrite
    energy_warn = cfg%run%energy_warn; energy_stop = cfg%run%energy_stop
    check_interval = cfg%run%check_interval; allow_unstable_dt = cfg%run%allow_unstable_dt
    checkpoint_interval = cfg%run%checkpoint_interval
    checkpoint_file = cfg%run%checkpoint_file; restart = cfg%run%restart
    repartition_step = cfg%run%repartition_step
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
    cfg%run%repartition_step = repartition_step
  end subroutine parse_run

  !> Check, parse and validate group g (&run) of the input into the configuration.
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
      'checkpoint_interval', 'checkpoint_file', 'restart', 'repartition_step'], label, stat, msg)
    if (stat /= 0) return
    call text%chunk(g, chunk)
    call parse_run(chunk, cfg, stat, iomsg)
    if (stat /= 0) then
      call read_error(text, g, label, iomsg, chunk, try_run, msg)
      stat = 1
      return
    end if
    call check_strings(text, g, label, [character(len=15) :: 'analysis', 'integrator', &
      'output_file', 'checkpoint_file', 'restart'], [16, 16, path_len, path_len, path_len], &
      stat, msg)
    if (stat /= 0) return
    associate(r => cfg%run)
      call check_reals(text, g, label, [character(len=19) :: 't_end', 'dt', 'dt_safety', &
        'output_interval', 'history_interval', 'progress_interval', 'energy_warn', &
        'energy_stop', 'checkpoint_interval'], [r%t_end, r%dt, r%dt_safety, r%output_interval, &
        r%history_interval, r%progress_interval, r%energy_warn, r%energy_stop, &
        r%checkpoint_interval], stat, msg)
    end associate
    if (stat == 0) call check_logicals(text, g, label, [character(len=17) :: 'overwrite', &
      'allow_unstable_dt'], stat, msg)
    if (stat /= 0) return
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
      else if (r%repartition_step < 0) then
        call bad(label, 'repartition_step', itoa(r%repartition_step), 'must be >= 0 [steps] '// &
                 '(0: never)', stat, msg)
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
      'check_interval', 'allow_unstable_dt', 'checkpoint_interval', 'checkpoint_file', 'restart', &
      'repartition_step']
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

  integer function try_run(part) result(ios)
    character(len=line_len), intent(in) :: part(:)
    type(config_t) :: c
    character(len=:), allocatable :: m
    call parse_run(part, c, ios, m)
  end function try_run

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

  !> Check, parse and validate group g (&static) of the input into the configuration.
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
      call read_error(text, g, label, iomsg, chunk, try_static, msg)
      stat = 1
      return
    end if
    call check_strings(text, g, label, [character(len=6) :: 'method', 'mass'], [8, 12], stat, &
                       msg)
    if (stat /= 0) return
    call check_reals(text, g, label, ['tolerance'], [cfg%static%tolerance], stat, msg)
    if (stat /= 0) return
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

  integer function try_static(part) result(ios)
    character(len=line_len), intent(in) :: part(:)
    type(config_t) :: c
    character(len=:), allocatable :: m
    call parse_static(part, c, ios, m)
  end function try_static

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

  !> Check, parse and validate group g (&initial) of the input into the configuration.
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
      call read_error(text, g, label, iomsg, chunk, try_initial, msg)
      stat = 1
      return
    end if
    call check_reals(text, g, label, [character(len=16) :: 'velocity', 'velocity', &
      'angular_velocity', 'center', 'center'], [cfg%initial%velocity, &
      cfg%initial%angular_velocity, cfg%initial%center], stat, msg)
    if (stat /= 0) return
    cfg%initial%given = .true.
  end subroutine read_initial

  integer function try_initial(part) result(ios)
    character(len=line_len), intent(in) :: part(:)
    type(config_t) :: c
    character(len=:), allocatable :: m
    call parse_initial(part, c, ios, m)
  end function try_initial

end module iem_input_control
