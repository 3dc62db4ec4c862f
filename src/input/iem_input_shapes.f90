!> Reader of the repeatable &shape group: a rectangle, circle or polygon that gives its
!> material (or 'void') to the cells whose centre it holds. Names of shapes and materials
!> are resolved later, with all groups read (iem_input_scene).
module iem_input_shapes
  use iem_kinds, only: wp
  use iem_constants, only: unset_real
  use iem_strings, only: itoa, rtoa, lower
  use iem_config, only: shape_config_t, name_len
  use iem_namelist_text, only: nml_text_t, line_len
  use iem_input_checks, only: bad, given
  use iem_input_table, only: key_t, key, key_only, read_group, check_literals, check_values
  implicit none
  private
  public :: read_shape, max_vertices, valid_name

  !> Most vertices of a polygon (points holds two values a vertex).
  integer, parameter :: max_vertices = 256
  !> Values points can hold: one vertex more than allowed, so that too many is named as such.
  integer, parameter :: n_values = 2*max_vertices + 2

contains

  !> True when name holds only letters, digits, _ - and . (names of materials and shapes).
  pure logical function valid_name(name)
    character(len=*), intent(in) :: name
    valid_name = verify(trim(name), 'abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ'// &
                        '0123456789_-.') == 0
  end function valid_name

  subroutine parse_shape(chunk, sh, ios, iomsg, points, n_given)
    character(len=line_len), intent(in) :: chunk(:)
    type(shape_config_t), intent(inout) :: sh
    integer, intent(out) :: ios
    character(len=256), intent(out) :: iomsg
    !> The polygon's values as read (unset where not given) and how many were given.
    real(wp), intent(out), optional :: points(n_values)
    integer, intent(out), optional :: n_given
    character(len=name_len) :: name, material
    character(len=12) :: kind
    real(wp) :: box(4), center(2), radius
    real(wp) :: p(n_values)
    name = ''; kind = ''; box = unset_real; center = unset_real; radius = unset_real
    p = unset_real; material = ''
    iomsg = ''
    call read_it(p)
    sh%name = name; sh%kind = lower(kind); sh%box = box; sh%center = center
    sh%radius = radius; sh%material = material
    if (present(points)) points = p
    if (present(n_given)) n_given = count(p /= unset_real)
  contains
    ! the namelist object must be called points; p is its storage
    subroutine read_it(points)
      real(wp), intent(inout) :: points(n_values)
      namelist /shape/ name, kind, box, center, radius, points, material
      read(chunk, nml=shape, iostat=ios, iomsg=iomsg)
    end subroutine read_it
  end subroutine parse_shape

  !> Check, parse and validate group g (&shape number is of the input) into sh.
  subroutine read_shape(text, g, is, sh, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g, is
    type(shape_config_t), intent(inout), target :: sh
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=256) :: iomsg
    character(len=:), allocatable :: label
    type(key_t) :: keys(7)
    real(wp) :: p(n_values)
    ! the values of points given (the others hold the unset marker)
    real(wp), allocatable, target :: given_points(:)
    integer :: n_given, n
    label = '&shape #'//itoa(is)//' (line '//itoa(text%groups(g)%first_line)//')'
    keys = [key('name', sh%name), &
      key('kind', sh%kind, need=": 'rectangle', 'circle' or 'polygon'", &
          allowed='rectangle circle polygon'), &
      key('box', sh%box), key('center', sh%center), key('radius', sh%radius), &
      key_only('points', 'r'), &
      key('material', sh%material, need=": the name of a &material, or 'void' to remove "// &
          "material")]
    call read_group(text, g, keys, label, try_shape, chunk, stat, msg)
    if (stat /= 0) return
    call parse_shape(chunk, sh, stat, iomsg, p, n_given)
    given_points = pack(p, p /= unset_real)
    keys(6) = key('points', given_points)
    call check_literals(text, g, keys, label, stat, msg)
    if (stat == 0) call check_values(keys, 'kind', label, stat, msg)
    if (stat == 0) call check_shape_applies()
    if (stat /= 0) return
    select case (trim(sh%kind))
    case ('rectangle')
      if (any(sh%box == unset_real)) then
        call bad(label, 'box', '(not given)', "is required for kind = 'rectangle': "// &
                 'x0, x1, y0, y1 [m]', stat, msg)
      else if (.not. (sh%box(1) < sh%box(2) .and. sh%box(3) < sh%box(4))) then
        call bad(label, 'box', rtoa(sh%box(1))//', '//rtoa(sh%box(2))//', '// &
                 rtoa(sh%box(3))//', '//rtoa(sh%box(4)), 'needs x0 < x1 and y0 < y1', stat, msg)
      end if
    case ('circle')
      if (any(sh%center == unset_real)) then
        call bad(label, 'center', '(not given)', "is required for kind = 'circle': x, y [m]", &
                 stat, msg)
      else if (sh%radius == unset_real) then
        call bad(label, 'radius', '(not given)', "is required for kind = 'circle' [m]", &
                 stat, msg)
      else if (.not. (sh%radius > 0.0_wp)) then
        call bad(label, 'radius', rtoa(sh%radius), 'must be > 0 [m]', stat, msg)
      end if
    case ('polygon')
      n = findloc(p == unset_real, .true., 1) - 1
      if (n < 0) n = size(p)
      if (n == 0) then
        call bad(label, 'points', '(not given)', "is required for kind = 'polygon': x1, y1, "// &
                 'x2, y2, ... (at least 3 vertices) [m]', stat, msg)
      else if (n /= n_given) then
        call bad(label, 'points', '', 'has an empty value between two given ones', stat, msg)
      else if (mod(n, 2) /= 0) then
        call bad(label, 'points', itoa(n)//' values', 'must be pairs x, y: an even count', &
                 stat, msg)
      else if (n < 6) then
        call bad(label, 'points', itoa(n/2)//' vertices', 'must give at least 3 vertices', &
                 stat, msg)
      else
        sh%points = reshape(p(1:n), [2, n/2])
        call check_polygon(sh%points, label, stat, msg)
      end if
    end select
    if (stat /= 0) return
    call check_values(keys, 'material', label, stat, msg)
    if (stat == 0 .and. .not. valid_name(sh%name)) then
      call bad(label, 'name', "'"//trim(sh%name)//"'", 'may hold only letters, digits, _ - '// &
               'and .', stat, msg)
    end if
    if (.not. allocated(sh%points)) allocate(sh%points(2, 0))
  contains
    !> Refuse a geometric variable that the shape's kind does not use.
    subroutine check_shape_applies()
      character(len=*), parameter :: vars(*) = [character(len=6) :: 'box', 'center', &
        'radius', 'points']
      character(len=*), parameter :: kinds(*) = [character(len=9) :: 'rectangle', 'circle', &
        'circle', 'polygon']
      integer :: k
      do k = 1, size(vars)
        if (given(text, g, trim(vars(k))) .and. trim(sh%kind) /= trim(kinds(k))) then
          call bad(label, trim(vars(k)), '', "applies only to kind = '"//trim(kinds(k))// &
                   "' (kind = '"//trim(sh%kind)//"')", stat, msg)
          return
        end if
      end do
    end subroutine check_shape_applies
  end subroutine read_shape

  integer function try_shape(part, iomsg) result(ios)
    character(len=line_len), intent(in) :: part(:)
    character(len=256), intent(out) :: iomsg
    type(shape_config_t) :: c
    call parse_shape(part, c, ios, iomsg)
  end function try_shape

  !> Refuse a polygon that is not simple: more than max_vertices vertices, two consecutive
  !> vertices at one point, no area, or two edges that touch or cross.
  subroutine check_polygon(v, label, stat, msg)
    real(wp), intent(in) :: v(:, :)
    character(len=*), intent(in) :: label
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer :: n, i, j
    real(wp) :: area, scale
    stat = 0
    msg = ''
    n = size(v, 2)
    if (n > max_vertices) then
      call bad(label, 'points', itoa(n)//' vertices', 'must give at most '// &
               itoa(max_vertices)//' vertices', stat, msg)
      return
    end if
    scale = max(maxval(v(1, :)) - minval(v(1, :)), maxval(v(2, :)) - minval(v(2, :)))
    do i = 1, n
      j = modulo(i, n) + 1
      if (all(v(:, i) == v(:, j))) then
        call bad(label, 'points', '', 'has vertices '//itoa(i)//' and '//itoa(j)// &
                 ' at one point ('//rtoa(v(1, i))//', '//rtoa(v(2, i))//')', stat, msg)
        return
      end if
    end do
    ! neighbouring edges that fold back onto each other (a spike) overlap along a stretch
    do i = 1, n
      j = modulo(i, n) + 1
      associate(a => v(:, i), b => v(:, j), c => v(:, modulo(j, n) + 1))
        if (abs(cross(a, b, c)) <= 1.0e-12_wp*norm2(b - a)*norm2(c - b) .and. &
            dot_product(b - a, c - b) < 0.0_wp) then
          call bad(label, 'points', '', 'is not a simple polygon: it folds back at vertex '// &
                   itoa(j), stat, msg)
          return
        end if
      end associate
    end do
    ! edges i (v(i) to v(i+1)) and j, not neighbours, must not meet
    do i = 1, n
      do j = i + 2, n
        if (i == 1 .and. j == n) cycle
        if (segments_meet(v(:, i), v(:, modulo(i, n) + 1), v(:, j), v(:, modulo(j, n) + 1))) &
          then
          call bad(label, 'points', '', 'is not a simple polygon: edge '//itoa(i)// &
                   ' (vertices '//itoa(i)//'-'//itoa(modulo(i, n) + 1)//') meets edge '// &
                   itoa(j)//' (vertices '//itoa(j)//'-'//itoa(modulo(j, n) + 1)//')', stat, msg)
          return
        end if
      end do
    end do
    area = 0.0_wp
    do i = 1, n
      j = modulo(i, n) + 1
      area = area + v(1, i)*v(2, j) - v(1, j)*v(2, i)
    end do
    if (.not. (abs(area) > 1.0e-12_wp*scale**2)) then
      call bad(label, 'points', '', 'encloses no area (the vertices are on one line)', &
               stat, msg)
    end if
  end subroutine check_polygon

  !> z of (b - a) x (c - a).
  pure real(wp) function cross(a, b, c)
    real(wp), intent(in) :: a(2), b(2), c(2)
    cross = (b(1) - a(1))*(c(2) - a(2)) - (b(2) - a(2))*(c(1) - a(1))
  end function cross

  !> True when the closed segments pq and rs have a point in common.
  pure logical function segments_meet(p, q, r, s) result(meet)
    real(wp), intent(in) :: p(2), q(2), r(2), s(2)
    real(wp) :: d1, d2, d3, d4
    d1 = cross(r, s, p)
    d2 = cross(r, s, q)
    d3 = cross(p, q, r)
    d4 = cross(p, q, s)
    if (((d1 > 0 .and. d2 < 0) .or. (d1 < 0 .and. d2 > 0)) .and. &
        ((d3 > 0 .and. d4 < 0) .or. (d3 < 0 .and. d4 > 0))) then
      meet = .true.
    else
      meet = (d1 == 0 .and. on_segment(r, s, p)) .or. (d2 == 0 .and. on_segment(r, s, q)) .or. &
             (d3 == 0 .and. on_segment(p, q, r)) .or. (d4 == 0 .and. on_segment(p, q, s))
    end if
  end function segments_meet

  !> True when x, known to be on the line ab, lies within the segment's bounding box.
  pure logical function on_segment(a, b, x)
    real(wp), intent(in) :: a(2), b(2), x(2)
    on_segment = x(1) >= min(a(1), b(1)) .and. x(1) <= max(a(1), b(1)) .and. &
                 x(2) >= min(a(2), b(2)) .and. x(2) <= max(a(2), b(2))
  end function on_segment
end module iem_input_shapes
