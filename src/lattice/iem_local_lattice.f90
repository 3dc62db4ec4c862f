!> One rank's part of the explicit lattice: owned nodes first (ascending global number), halo
!> nodes after (grouped by owning rank), and the cells touching owned nodes (ascending global
!> number), each with its corner nodes, material and open edges. The time loop reads only the
!> cell-to-node table and the materials; numbers and grid indices serve set-up and output.
module iem_local_lattice
  use, intrinsic :: iso_fortran_env, only: int8
  use iem_kinds, only: wp, ip, i8
  implicit none
  private
  public :: local_lattice_t

  !> Local lattice of one rank.
  type :: local_lattice_t
    integer :: n_owned = 0, n_local = 0, n_cells = 0
    !> Global 0-based number of each local node and its grid indices (i, j) (2, n_local):
    !> its reference coordinates are (i lx, j ly) (node_xy), with the grid's cell sizes.
    integer(i8), allocatable :: gid(:)
    integer, allocatable :: ij(:, :)
    real(wp) :: lx = 0.0_wp, ly = 0.0_wp
    !> Local corner nodes of each local cell, counter-clockwise from lower left.
    integer(ip), allocatable :: cell_nodes(:, :)
    !> Global 0-based number of each local cell, its material (1..), and its open edges: bit
    !> q-1 set when edge q (bottom, right, top, left) lies on the boundary of the body.
    integer(i8), allocatable :: cell_gid(:)
    integer, allocatable :: cell_mat(:)
    integer(int8), allocatable :: cell_open(:)
    !> With shapes only: the shape that decided each cell (0: the background or the image), and
    !> the one that decided the grid cell across each edge (side_src(q, c); -1: outside the
    !> grid), for the node sets on a shape's outline.
    integer(int8), allocatable :: cell_src(:), side_src(:, :)
    !> Whether the lattice has more than one material (the kernel then reads cell_mat).
    logical :: mixed = .false.
  contains
    procedure :: node_xy => local_lattice_node_xy
    procedure :: cell_counted => local_lattice_cell_counted
    procedure :: n_counted => local_lattice_n_counted
    procedure :: edge_open => local_lattice_edge_open
    procedure :: free => local_lattice_free
  end type local_lattice_t

contains

  !> Reference coordinates (x, y) of local node l.
  pure function local_lattice_node_xy(this, l) result(xy)
    class(local_lattice_t), intent(in) :: this
    integer, intent(in) :: l
    real(wp) :: xy(2)
    xy = [this%ij(1, l)*this%lx, this%ij(2, l)*this%ly]
  end function local_lattice_node_xy

  !> True for the cells this rank counts in global sums and writes: those whose first corner
  !> it owns (each cell is counted by exactly one rank).
  pure logical function local_lattice_cell_counted(this, c) result(counted)
    class(local_lattice_t), intent(in) :: this
    integer, intent(in) :: c
    counted = this%cell_nodes(1, c) <= this%n_owned
  end function local_lattice_cell_counted

  !> Number of cells this rank counts.
  pure integer function local_lattice_n_counted(this) result(n)
    class(local_lattice_t), intent(in) :: this
    n = count(this%cell_nodes(1, 1:this%n_cells) <= this%n_owned)
  end function local_lattice_n_counted

  !> True when edge q (1 bottom, 2 right, 3 top, 4 left) of local cell c is on the boundary.
  pure logical function local_lattice_edge_open(this, c, q) result(open)
    class(local_lattice_t), intent(in) :: this
    integer, intent(in) :: c, q
    open = btest(this%cell_open(c), q - 1)
  end function local_lattice_edge_open

  !> Release all arrays.
  subroutine local_lattice_free(this)
    class(local_lattice_t), intent(inout) :: this
    if (allocated(this%gid)) deallocate(this%gid)
    if (allocated(this%ij)) deallocate(this%ij)
    if (allocated(this%cell_nodes)) deallocate(this%cell_nodes)
    if (allocated(this%cell_gid)) deallocate(this%cell_gid)
    if (allocated(this%cell_mat)) deallocate(this%cell_mat)
    if (allocated(this%cell_open)) deallocate(this%cell_open)
    if (allocated(this%cell_src)) deallocate(this%cell_src)
    if (allocated(this%side_src)) deallocate(this%side_src)
    this%n_owned = 0
    this%n_local = 0
    this%n_cells = 0
    this%mixed = .false.
  end subroutine local_lattice_free
end module iem_local_lattice
