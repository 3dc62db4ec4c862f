!> Reads the namelist input: rank 0 reads the file, every rank parses the same broadcast text
!> and validates it, so that all ranks agree on every error. Errors name group, variable, value.
module iem_input
  use mpi_f08, only: MPI_Comm
  use iem_kinds, only: wp
  use iem_strings, only: itoa, rtoa
  use iem_config, only: config_t
  use iem_namelist_text, only: nml_text_t
  use iem_input_checks, only: bad
  use iem_input_control, only: read_run, read_static, read_initial
  use iem_input_body, only: read_geometry, read_material, read_damping
  use iem_input_sets, only: read_bc, read_load, read_probe
  use iem_input_files, only: check_files
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
    allocate(cfg%materials(1), cfg%shapes(0))

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
    if (cfg%materials(1)%nonlinear .and. cfg%geometry%cell /= 'paper') then
      call bad('&geometry', 'cell', "'"//trim(cfg%geometry%cell)//"'", "cannot be used with "// &
               "nonlinear springs (&material nonlinear = .true.): use cell = 'paper'", stat, msg)
      return
    end if
    tol = 1.0e-9_wp*max(cfg%geometry%length, cfg%geometry%height)
    ! a point outside the body is refused, as for probes, rather than moved to the nearest node
    do k = 1, size(cfg%bcs)
      if (cfg%bcs(k)%set%where /= 'point') cycle
      if (outside(cfg%bcs(k)%set%point)) then
        call bad('&bc #'//itoa(k), 'point', rtoa(cfg%bcs(k)%set%point(1))//', '// &
                 rtoa(cfg%bcs(k)%set%point(2)), body_text(), stat, msg)
        return
      end if
    end do
    do k = 1, size(cfg%loads)
      if (cfg%loads(k)%set%where /= 'point') cycle
      if (outside(cfg%loads(k)%set%point)) then
        call bad('&load #'//itoa(k), 'point', rtoa(cfg%loads(k)%set%point(1))//', '// &
                 rtoa(cfg%loads(k)%set%point(2)), body_text(), stat, msg)
        return
      end if
    end do
    do k = 1, size(cfg%probes)
      associate(p => cfg%probes(k))
        if (outside([p%x, p%y])) then
          call bad('&probe #'//itoa(k), 'x, y', rtoa(p%x)//', '//rtoa(p%y), body_text(), &
                   stat, msg)
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
  contains

    logical function outside(xy)
      real(wp), intent(in) :: xy(2)
      outside = xy(1) < -tol .or. xy(1) > cfg%geometry%length + tol .or. &
                xy(2) < -tol .or. xy(2) > cfg%geometry%height + tol
    end function outside

    function body_text() result(t)
      character(len=:), allocatable :: t
      t = 'is outside the body [0, '//rtoa(cfg%geometry%length)//'] x [0, '// &
          rtoa(cfg%geometry%height)//']'
    end function body_text
  end subroutine check_cross
end module iem_input
