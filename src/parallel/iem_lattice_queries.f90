!> Questions about the body that its distributed lattice answers collectively, each rank
!> looking at its own nodes and cells only: the node nearest to a point, the place of a node
!> by its number, and the cell that holds a point.
module iem_lattice_queries
  use mpi_f08, only: MPI_Comm, MPI_Allreduce, MPI_IN_PLACE, MPI_MIN, MPI_MAX, MPI_SUM, &
                     MPI_MINLOC, MPI_INTEGER8, MPI_2DOUBLE_PRECISION, MPI_DOUBLE_PRECISION
  use iem_kinds, only: wp, i8
  use iem_grid, only: grid_t
  use iem_local_lattice, only: local_lattice_t
  use iem_config, only: config_t
  implicit none
  private
  public :: nearest_node, node_place, cell_holding, resolve_point_sets

contains

  !> The node of the body nearest to (x, y): the nearest grid node when the body uses it,
  !> else the nearest node of the body (ties: the lowest number). Collective.
  integer(i8) function nearest_node(grid, lat, comm, x, y) result(best)
    type(grid_t), intent(in) :: grid
    type(local_lattice_t), intent(in) :: lat
    type(MPI_Comm), intent(in) :: comm
    real(wp), intent(in) :: x, y
    integer :: l, i, j
    real(wp) :: dl(2), xl(2), d
    integer(i8) :: mine(1)
    i = min(max(nint(x/grid%lx), 0), grid%nx)
    j = min(max(nint(y/grid%ly), 0), grid%ny)
    mine = huge(1_i8)
    do l = 1, lat%n_owned
      if (all(lat%node_ij(l) == [i, j])) mine = lat%node_gid(l)
    end do
    call MPI_Allreduce(MPI_IN_PLACE, mine, 1, MPI_INTEGER8, MPI_MIN, comm)
    best = mine(1)
    if (best /= huge(1_i8)) return
    ! the grid node is not in the body: the nearest node, ties to the lowest number (MINLOC)
    dl = [huge(1.0_wp), huge(1.0_wp)]
    do l = 1, lat%n_owned
      xl = lat%node_xy(l)
      d = (xl(1) - x)**2 + (xl(2) - y)**2
      if (d < dl(1) .or. (d == dl(1) .and. real(lat%node_gid(l), wp) < dl(2))) &
        dl = [d, real(lat%node_gid(l), wp)]
    end do
    call MPI_Allreduce(MPI_IN_PLACE, dl, 1, MPI_2DOUBLE_PRECISION, MPI_MINLOC, comm)
    best = int(dl(2), i8)
  end function nearest_node

  !> Find the node of every 'point' set of the supports and loads of cfg (set%node), for
  !> select_nodes. Collective.
  subroutine resolve_point_sets(cfg, grid, lat, comm)
    type(config_t), intent(inout) :: cfg
    type(grid_t), intent(in) :: grid
    type(local_lattice_t), intent(in) :: lat
    type(MPI_Comm), intent(in) :: comm
    integer :: k
    do k = 1, size(cfg%bcs)
      associate(s => cfg%bcs(k)%set)
        if (s%where == 'point') s%node = nearest_node(grid, lat, comm, s%point(1), s%point(2))
      end associate
    end do
    do k = 1, size(cfg%loads)
      associate(s => cfg%loads(k)%set)
        if (s%where == 'point') s%node = nearest_node(grid, lat, comm, s%point(1), s%point(2))
      end associate
    end do
  end subroutine resolve_point_sets

  !> Reference coordinates of node g of the body (from the rank that owns it). Collective.
  function node_place(lat, comm, g) result(xy)
    type(local_lattice_t), intent(in) :: lat
    type(MPI_Comm), intent(in) :: comm
    integer(i8), intent(in) :: g
    real(wp) :: xy(2)
    integer :: l
    xy = 0.0_wp
    do l = 1, lat%n_owned
      if (lat%node_gid(l) == g) xy = lat%node_xy(l)
    end do
    call MPI_Allreduce(MPI_IN_PLACE, xy, 2, MPI_DOUBLE_PRECISION, MPI_SUM, comm)
  end function node_place

  !> The cell of the body that holds (x, y) (points on the far sides of the grid belong to
  !> the last cells) and its material; cell = -1 and mat = 0 when that grid cell is void.
  !> Collective.
  subroutine cell_holding(grid, lat, comm, x, y, cell, mat)
    type(grid_t), intent(in) :: grid
    type(local_lattice_t), intent(in) :: lat
    type(MPI_Comm), intent(in) :: comm
    real(wp), intent(in) :: x, y
    integer(i8), intent(out) :: cell
    integer, intent(out) :: mat
    integer :: i, j, c
    integer(i8) :: v(2)
    i = min(max(int(x/grid%lx), 0), grid%nx - 1)
    j = min(max(int(y/grid%ly), 0), grid%ny - 1)
    v = -1
    do c = 1, lat%n_cells
      if (.not. lat%cell_counted(c)) cycle
      if (all(lat%node_ij(lat%cell_nodes(1, c)) == [i, j])) &
        v = [lat%cell_gid(c), int(lat%mat(c), i8)]
    end do
    call MPI_Allreduce(MPI_IN_PLACE, v, 2, MPI_INTEGER8, MPI_MAX, comm)
    cell = v(1)
    mat = int(max(v(2), 0_i8))
  end subroutine cell_holding
end module iem_lattice_queries
