!> Node sets of the body, for supports, loads and probes (docs/input.md, "Node sets"): by
!> position (a side of the grid, a box, a point's nearest node, a segment, a disc, all nodes)
!> or by the body's boundary (all of it, the outline of a shape, a face by its outward
!> normal); and the boundary length each node carries for a traction on the set.
module iem_node_sets
  use iem_kinds, only: wp, i8
  use iem_body, only: body_t
  use iem_local_lattice, only: local_lattice_t
  use iem_config, only: node_set_spec_t
  implicit none
  private
  public :: select_nodes

  !> Outward normals of the edges of a cell: bottom, right, top, left.
  real(wp), parameter :: edge_normal(2, 4) = reshape([0.0_wp, -1.0_wp, 1.0_wp, 0.0_wp, &
                                                      0.0_wp, 1.0_wp, -1.0_wp, 0.0_wp], [2, 4])

contains

  !> The owned nodes of lat in the set spec (mask(n_owned)); with weight(n_owned), the length
  !> of the set's boundary each carries: half of every open edge of the set that ends at it.
  !> An open edge belongs to a set by position when both its nodes do; to a boundary set when
  !> it satisfies the set's rule. A 'point' set selects the node spec%node (see nearest_node).
  subroutine select_nodes(spec, body, lat, mask, weight)
    type(node_set_spec_t), intent(in) :: spec
    type(body_t), intent(in) :: body
    type(local_lattice_t), intent(in) :: lat
    logical, intent(out) :: mask(:)
    real(wp), intent(out), optional :: weight(:)
    logical, allocatable :: in_set(:)
    integer(i8) :: target, g0
    integer :: l, c, q, a, b, r, l0, l1, i0, j
    real(wp) :: len
    logical :: edge_set, take

    edge_set = any(trim(spec%where) == [character(len=8) :: 'boundary', 'shape', 'face'])
    allocate(in_set(lat%n_local))
    in_set = .false.
    if (.not. edge_set) then
      target = spec%node
      ! the owned nodes run by run, the halo nodes one by one
      do r = 1, lat%node_runs%n
        call lat%owned_run(r, l0, l1, i0, j, g0)
        do l = l0, l1
          in_set(l) = node_in(spec, body, [(i0 + l - l0)*lat%lx, j*lat%ly], g0 + (l - l0), &
                              target)
        end do
      end do
      do l = lat%n_owned + 1, lat%n_local
        in_set(l) = node_in(spec, body, lat%node_xy(l), lat%node_gid(l), target)
      end do
    end if
    if (present(weight)) weight = 0.0_wp
    do c = 1, lat%n_cells
      if (lat%cell_open(c) == 0) cycle
      do q = 1, 4
        if (.not. lat%edge_open(c, q)) cycle
        a = lat%cell_nodes(q, c)
        b = lat%cell_nodes(mod(q, 4) + 1, c)
        if (edge_set) then
          take = edge_in(spec, lat, c, q)
          if (take) then
            in_set(a) = .true.
            in_set(b) = .true.
          end if
        else
          take = in_set(a) .and. in_set(b)
        end if
        if (take .and. present(weight)) then
          len = merge(body%grid%lx, body%grid%ly, mod(q, 2) == 1)
          if (a <= lat%n_owned) weight(a) = weight(a) + 0.5_wp*len
          if (b <= lat%n_owned) weight(b) = weight(b) + 0.5_wp*len
        end if
      end do
    end do
    mask = in_set(1:lat%n_owned)
  end subroutine select_nodes

  !> Whether the node g at xy belongs to a set defined by position (target: the node a
  !> 'point' set selects).
  pure logical function node_in(spec, body, xy, g, target) result(inside)
    type(node_set_spec_t), intent(in) :: spec
    type(body_t), intent(in) :: body
    real(wp), intent(in) :: xy(2)
    integer(i8), intent(in) :: g, target
    real(wp) :: tol, d(2), s(2), t
    associate(grid => body%grid, x => xy(1), y => xy(2))
      tol = 1.0e-6_wp*min(grid%lx, grid%ly)
      select case (trim(spec%where))
      case ('left')
        inside = x <= tol
      case ('right')
        inside = x >= grid%nx*grid%lx - tol
      case ('bottom')
        inside = y <= tol
      case ('top')
        inside = y >= grid%ny*grid%ly - tol
      case ('all')
        inside = .true.
      case ('box')
        inside = x >= spec%box(1) - tol .and. x <= spec%box(2) + tol .and. &
                 y >= spec%box(3) - tol .and. y <= spec%box(4) + tol
      case ('point')
        inside = g == target
      case ('segment')
        ! distance from the segment (x0, y0)-(x1, y1)
        s = spec%segment(3:4) - spec%segment(1:2)
        d = xy - spec%segment(1:2)
        t = 0.0_wp
        if (dot_product(s, s) > 0.0_wp) t = min(max(dot_product(d, s)/dot_product(s, s), &
                                                    0.0_wp), 1.0_wp)
        inside = norm2(d - t*s) <= tol
      case ('circle')
        inside = norm2(xy - spec%center) <= spec%radius + tol
      case default
        inside = .false.
      end select
    end associate
  end function node_in

  !> Whether open edge q of local cell c belongs to a boundary set ('boundary', 'shape',
  !> 'face').
  pure logical function edge_in(spec, lat, c, q) result(inside)
    type(node_set_spec_t), intent(in) :: spec
    type(local_lattice_t), intent(in) :: lat
    integer, intent(in) :: c, q
    real(wp) :: n(2)
    select case (trim(spec%where))
    case ('boundary')
      inside = .true.
    case ('face')
      n = spec%normal/norm2(spec%normal)
      inside = dot_product(n, edge_normal(:, q)) >= 0.999_wp
    case ('shape')
      inside = .false.
      if (allocated(lat%cell_src)) inside = lat%cell_src(c) == spec%shape_id .or. &
                                            lat%side_src(q, c) == spec%shape_id
    case default
      inside = .false.
    end select
  end function edge_in
end module iem_node_sets
