!> One rank's part of the lattice: owned nodes first (ascending global index), halo nodes after
!> (grouped by owning rank), and the cells touching owned nodes (ascending global index).
!> Only what the time loop needs is stored (8 bytes a node, 16 a cell); grid indices, cell
!> indices and which rank counts a cell are derived from them on demand.
module iem_local_lattice
  use iem_kinds, only: ip, i8
  implicit none
  private
  public :: local_lattice_t

  !> Local lattice of one rank.
  type :: local_lattice_t
    integer :: n_owned = 0, n_local = 0, n_cells = 0
    !> Cells of the global grid in x and y.
    integer :: nx = 0, ny = 0
    !> Global 0-based node index of each local node.
    integer(i8), allocatable :: gid(:)
    !> Local corner nodes of each local cell, counter-clockwise from lower left.
    integer(ip), allocatable :: cell_nodes(:, :)
  contains
    procedure :: node_ij => local_lattice_node_ij
    procedure :: node_corners => local_lattice_node_corners
    procedure :: cell_gid => local_lattice_cell_gid
    procedure :: cell_counted => local_lattice_cell_counted
    procedure :: n_counted => local_lattice_n_counted
    procedure :: free => local_lattice_free
  end type local_lattice_t

contains

  !> Grid indices (i, j) of local node l.
  pure function local_lattice_node_ij(this, l) result(ij)
    class(local_lattice_t), intent(in) :: this
    integer, intent(in) :: l
    integer :: ij(2)
    ij(1) = int(mod(this%gid(l), int(this%nx + 1, i8)))
    ij(2) = int(this%gid(l)/int(this%nx + 1, i8))
  end function local_lattice_node_ij

  !> For local node l, its corner number (1-4) in each of its cells SW, SE, NW, NE of it, or 0
  !> where the grid has no such cell.
  pure function local_lattice_node_corners(this, l) result(corners)
    class(local_lattice_t), intent(in) :: this
    integer, intent(in) :: l
    integer :: corners(4), ij(2)
    ij = this%node_ij(l)
    corners = [3, 4, 2, 1]
    if (ij(1) == 0) corners([1, 3]) = 0
    if (ij(1) == this%nx) corners([2, 4]) = 0
    if (ij(2) == 0) corners([1, 2]) = 0
    if (ij(2) == this%ny) corners([3, 4]) = 0
  end function local_lattice_node_corners

  !> Global 0-based index of local cell c (from its first corner).
  pure integer(i8) function local_lattice_cell_gid(this, c) result(g)
    class(local_lattice_t), intent(in) :: this
    integer, intent(in) :: c
    integer :: ij(2)
    ij = this%node_ij(this%cell_nodes(1, c))
    g = int(ij(1), i8) + int(ij(2), i8)*this%nx
  end function local_lattice_cell_gid

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

  !> Release all arrays.
  subroutine local_lattice_free(this)
    class(local_lattice_t), intent(inout) :: this
    if (allocated(this%gid)) deallocate(this%gid)
    if (allocated(this%cell_nodes)) deallocate(this%cell_nodes)
    this%n_owned = 0
    this%n_local = 0
    this%n_cells = 0
  end subroutine local_lattice_free
end module iem_local_lattice
