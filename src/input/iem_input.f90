!> Reads the namelist input: rank 0 reads the file, every rank parses the same broadcast text
!> and validates it, so that all ranks agree on every error. Errors name group, variable, value.
module iem_input
  use mpi_f08, only: MPI_Comm
  use iem_kinds, only: wp
  use iem_strings, only: itoa, rtoa
  use iem_config, only: config_t, node_set_spec_t, shape_config_t
  use iem_namelist_text, only: nml_text_t
  use iem_input_checks, only: bad
  use iem_input_control, only: read_run, read_static, read_initial
  use iem_input_body, only: read_geometry, read_material, read_damping
  use iem_input_sets, only: read_bc, read_load, read_probe
  use iem_input_shapes, only: read_shape
  use iem_input_scene, only: resolve_scene, label_len
  use iem_input_image, only: check_image
  use iem_input_fracture, only: check_fracture_cells, check_fracture_scene
  use iem_input_files, only: check_files
  implicit none
  private
  public :: read_config

  character(len=*), parameter :: known_groups(*) = [character(len=8) :: &
    'run', 'geometry', 'material', 'damping', 'bc', 'load', 'probe', 'static', 'initial', &
    'shape']
  logical, parameter :: repeatable(*) = [.false., .false., .true., .false., .true., .true., &
    .true., .false., .false., .true.]
  logical, parameter :: required(*) = [.true., .true., .true., .false., .false., .false., &
    .false., .false., .false., .false.]

contains

  !> Read, parse and validate the namelist file; collective; stat /= 0 with msg on every rank.
  subroutine read_config(path, comm, cfg, stat, msg)
    character(len=*), intent(in) :: path
    type(MPI_Comm), intent(in) :: comm
    type(config_t), intent(out) :: cfg
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    type(nml_text_t) :: text
    integer :: g, k, count(size(known_groups)), ib, il, ip, im, is
    character(len=label_len), allocatable :: mat_labels(:), shape_labels(:), bc_labels(:), &
      load_labels(:)

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
                  '&material, &shape, &damping, &bc, &load, &probe, &static, &initial)')
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
    allocate(cfg%materials(count(3)), cfg%shapes(count(10)))
    allocate(mat_labels(count(3)), shape_labels(count(10)), bc_labels(count(5)), &
             load_labels(count(6)))

    ib = 0; il = 0; ip = 0; im = 0; is = 0
    do g = 1, text%n_groups
      select case (trim(text%groups(g)%name))
      case ('run')
        call read_run(text, g, cfg, stat, msg)
      case ('geometry')
        call read_geometry(text, g, cfg, stat, msg)
      case ('material')
        im = im + 1
        ! one &material keeps the plain label of the inputs that have always had one
        mat_labels(im) = '&material'
        if (count(3) > 1) mat_labels(im) = label_of('material', im, g)
        call read_material(text, g, trim(mat_labels(im)), cfg%materials(im), stat, msg)
      case ('shape')
        is = is + 1
        shape_labels(is) = label_of('shape', is, g)
        call read_shape(text, g, is, cfg%shapes(is), stat, msg)
      case ('damping')
        call read_damping(text, g, cfg, stat, msg)
      case ('bc')
        ib = ib + 1
        bc_labels(ib) = label_of('bc', ib, g)
        call read_bc(text, g, ib, cfg%bcs(ib), stat, msg)
      case ('load')
        il = il + 1
        load_labels(il) = label_of('load', il, g)
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
    call resolve_scene(cfg, mat_labels, shape_labels, bc_labels, load_labels, stat, msg)
    if (stat == 0) call check_cross(cfg, stat, msg)
    if (stat == 0) call check_image(cfg, comm, stat, msg)
    if (stat == 0) call check_fracture_scene(cfg, mat_labels, shape_labels, stat, msg)
    ! the grid is known now (an image sets it): no softening branch may snap back on it
    if (stat == 0 .and. cfg%geometry%nx > 0 .and. cfg%geometry%ny > 0) &
      call check_fracture_cells(cfg, mat_labels, cfg%geometry%length/cfg%geometry%nx, &
                                cfg%geometry%height/cfg%geometry%ny, stat, msg)
    if (stat /= 0) then
      msg = trim(path)//': '//msg
      return
    end if
    call check_files(cfg, comm, stat, msg)

  contains

    !> '&group #k (line N)' for instance k of a repeatable group (group g of the text).
    function label_of(group, k, g) result(label)
      character(len=*), intent(in) :: group
      integer, intent(in) :: k, g
      character(len=label_len) :: label
      label = '&'//group//' #'//itoa(k)//' (line '//itoa(text%groups(g)%first_line)//')'
    end function label_of

    subroutine fail(text_)
      character(len=*), intent(in) :: text_
      stat = 1
      msg = trim(path)//': '//text_
    end subroutine fail
  end subroutine read_config

  !> Checks that involve several groups: &static only with a static analysis, points,
  !> segments, circles, shapes and probes inside the background rectangle, unique probe names.
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
    tol = 1.0e-9_wp*max(cfg%geometry%length, cfg%geometry%height)
    ! a point outside the body is refused, as for probes, rather than moved to the nearest
    ! node; so are segment ends and circles that miss the background rectangle
    do k = 1, size(cfg%bcs)
      call check_set_inside(cfg%bcs(k)%set, '&bc #'//itoa(k))
      if (stat /= 0) return
    end do
    do k = 1, size(cfg%loads)
      call check_set_inside(cfg%loads(k)%set, '&load #'//itoa(k))
      if (stat /= 0) return
    end do
    do k = 1, size(cfg%shapes)
      if (misses(cfg%shapes(k))) then
        call bad('&shape #'//itoa(k), 'kind', "'"//trim(cfg%shapes(k)%kind)//"'", &
                 'lies wholly outside the background rectangle [0, '// &
                 rtoa(cfg%geometry%length)//'] x [0, '//rtoa(cfg%geometry%height)//']', &
                 stat, msg)
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

    subroutine check_set_inside(set, label)
      type(node_set_spec_t), intent(in) :: set
      character(len=*), intent(in) :: label
      real(wp) :: d(2)
      select case (trim(set%where))
      case ('point')
        if (outside(set%point)) call bad(label, 'point', rtoa(set%point(1))//', '// &
          rtoa(set%point(2)), body_text(), stat, msg)
      case ('segment')
        if (outside(set%segment(1:2)) .or. outside(set%segment(3:4))) call bad(label, &
          'segment', rtoa(set%segment(1))//', '//rtoa(set%segment(2))//', '// &
          rtoa(set%segment(3))//', '//rtoa(set%segment(4)), 'has an end '//body_text(), &
          stat, msg)
      case ('circle')
        ! distance from the centre to the rectangle
        d = max([0.0_wp, 0.0_wp], max(-set%center, set%center - [cfg%geometry%length, &
                cfg%geometry%height]))
        if (norm2(d) > set%radius + tol) call bad(label, 'center, radius', &
          rtoa(set%center(1))//', '//rtoa(set%center(2))//', '//rtoa(set%radius), &
          'is a disc wholly outside the body [0, '//rtoa(cfg%geometry%length)//'] x [0, '// &
          rtoa(cfg%geometry%height)//']', stat, msg)
      end select
    end subroutine check_set_inside

    !> True when the bounding box of shape sh does not meet the background rectangle.
    logical function misses(sh)
      type(shape_config_t), intent(in) :: sh
      real(wp) :: b(4)
      select case (trim(sh%kind))
      case ('rectangle')
        b = sh%box
      case ('circle')
        b = [sh%center(1) - sh%radius, sh%center(1) + sh%radius, &
             sh%center(2) - sh%radius, sh%center(2) + sh%radius]
      case default
        b = [minval(sh%points(1, :)), maxval(sh%points(1, :)), minval(sh%points(2, :)), &
             maxval(sh%points(2, :))]
      end select
      misses = b(2) < -tol .or. b(1) > cfg%geometry%length + tol .or. &
               b(4) < -tol .or. b(3) > cfg%geometry%height + tol
    end function misses

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
