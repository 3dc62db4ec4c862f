!> Shapes that cut a body out of a background grid of cells (issue 10, first part): rectangles,
!> circles and polygons, each adding material (a material id > 0) or removing it (void, 0).
!> A cell belongs to what the last shape containing its centre says (later shapes win);
!> docs/model.md states the rule. Pure, so that each rank can classify only its own cells.
module iem_shapes
  use iem_kinds, only: wp
  implicit none
  private
  public :: shape_t, shape_rectangle, shape_circle, shape_polygon, shape_contains
  public :: material_at, shape_none, shape_rect, shape_circ, shape_poly

  !> Kinds of shape.
  integer, parameter :: shape_none = 0, shape_rect = 1, shape_circ = 2, shape_poly = 3

  !> One shape: its kind, the material it gives (0: it removes material) and its geometry:
  !> a rectangle [x0, x1] x [y0, y1] (p = x0, x1, y0, y1), a circle (p = cx, cy, r), or a
  !> polygon of vertices v(2, n) in either orientation (not necessarily convex).
  type :: shape_t
    integer :: kind = shape_none
    integer :: material = 0
    real(wp) :: p(4) = 0.0_wp
    real(wp), allocatable :: v(:, :)
  end type shape_t

contains

  !> The rectangle [x0, x1] x [y0, y1] giving material (0: a hole).
  pure function shape_rectangle(x0, x1, y0, y1, material) result(s)
    real(wp), intent(in) :: x0, x1, y0, y1
    integer, intent(in) :: material
    type(shape_t) :: s
    s%kind = shape_rect
    s%material = material
    s%p = [min(x0, x1), max(x0, x1), min(y0, y1), max(y0, y1)]
  end function shape_rectangle

  !> The circle of centre (cx, cy) and radius r giving material (0: a hole).
  pure function shape_circle(cx, cy, r, material) result(s)
    real(wp), intent(in) :: cx, cy, r
    integer, intent(in) :: material
    type(shape_t) :: s
    s%kind = shape_circ
    s%material = material
    s%p = [cx, cy, abs(r), 0.0_wp]
  end function shape_circle

  !> The polygon of vertices v(2, n), n >= 3, giving material (0: a hole).
  pure function shape_polygon(v, material) result(s)
    real(wp), intent(in) :: v(:, :)
    integer, intent(in) :: material
    type(shape_t) :: s
    s%kind = shape_poly
    s%material = material
    allocate(s%v, source=v)
  end function shape_polygon

  !> True when the point (x, y) is inside shape s. Points on the boundary of a rectangle or
  !> a circle are inside; a polygon uses the crossing rule with half-open edges, so that of
  !> two polygons sharing an edge exactly one holds a point on it.
  pure logical function shape_contains(s, x, y) result(inside)
    type(shape_t), intent(in) :: s
    real(wp), intent(in) :: x, y
    integer :: k, n, j
    real(wp) :: xc
    inside = .false.
    select case (s%kind)
    case (shape_rect)
      inside = x >= s%p(1) .and. x <= s%p(2) .and. y >= s%p(3) .and. y <= s%p(4)
    case (shape_circ)
      inside = (x - s%p(1))**2 + (y - s%p(2))**2 <= s%p(3)**2
    case (shape_poly)
      n = size(s%v, 2)
      j = n
      do k = 1, n
        ! edge from vertex j to vertex k, counted when it straddles the line y (half-open)
        if ((s%v(2, k) > y) .neqv. (s%v(2, j) > y)) then
          xc = s%v(1, j) + (y - s%v(2, j))*(s%v(1, k) - s%v(1, j))/(s%v(2, k) - s%v(2, j))
          if (x < xc) inside = .not. inside
        end if
        j = k
      end do
    end select
  end function shape_contains

  !> The material at (x, y): that of the last shape that contains it, else background
  !> (0: void).
  pure integer function material_at(shapes, x, y, background) result(m)
    type(shape_t), intent(in) :: shapes(:)
    real(wp), intent(in) :: x, y
    integer, intent(in) :: background
    integer :: k
    m = background
    do k = size(shapes), 1, -1
      if (shape_contains(shapes(k), x, y)) then
        m = shapes(k)%material
        return
      end if
    end do
  end function material_at
end module iem_shapes
