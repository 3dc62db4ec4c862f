!> Node sets chosen by named edges, boxes, a point (nearest node) or all nodes.
module iem_node_sets
  use iem_kinds, only: wp, i8
  use iem_grid, only: grid_t
  use iem_config, only: node_set_spec_t
  implicit none
  private
  public :: in_node_set, edge_weight

contains

  !> True when grid node (i, j) belongs to the set described by spec.
  pure logical function in_node_set(spec, grid, i, j) result(inside)
    type(node_set_spec_t), intent(in) :: spec
    type(grid_t), intent(in) :: grid
    integer, intent(in) :: i, j
    real(wp) :: x, y, tol
    integer(i8) :: g
    select case (trim(spec%where))
    case ('left')
      inside = i == 0
    case ('right')
      inside = i == grid%nx
    case ('bottom')
      inside = j == 0
    case ('top')
      inside = j == grid%ny
    case ('all')
      inside = .true.
    case ('box')
      tol = 1.0e-6_wp*min(grid%lx, grid%ly)
      x = i*grid%lx
      y = j*grid%ly
      inside = x >= spec%box(1) - tol .and. x <= spec%box(2) + tol .and. &
               y >= spec%box(3) - tol .and. y <= spec%box(4) + tol
    case ('point')
      g = grid%nearest_node(spec%point(1), spec%point(2))
      inside = g == grid%node_id(i, j)
    case default
      inside = .false.
    end select
  end function in_node_set

  !> Length of edge boundary (m) that node (i, j) carries on a named edge (trapezoid rule).
  pure real(wp) function edge_weight(where, grid, i, j) result(w)
    character(len=*), intent(in) :: where
    type(grid_t), intent(in) :: grid
    integer, intent(in) :: i, j
    select case (trim(where))
    case ('bottom', 'top')
      w = grid%lx
      if (i == 0 .or. i == grid%nx) w = 0.5_wp*grid%lx
    case ('left', 'right')
      w = grid%ly
      if (j == 0 .or. j == grid%ny) w = 0.5_wp*grid%ly
    case default
      w = 0.0_wp
    end select
  end function edge_weight
end module iem_node_sets
