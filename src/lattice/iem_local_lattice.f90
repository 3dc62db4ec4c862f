!> One rank's part of the lattice: owned nodes first (ascending global index), halo nodes after
!> (grouped by owning rank), the cells touching owned nodes, and the node-to-cell gather table.
module iem_local_lattice
  use iem_kinds, only: ip, i8
  implicit none
  private
  public :: local_lattice_t

  !> Local lattice of one rank.
  type :: local_lattice_t
    integer :: n_owned = 0, n_local = 0, n_cells = 0
    !> Global 0-based node index of each local node.
    integer(i8), allocatable :: gid(:)
    !> Grid indices (i, j) of each local node.
    integer(ip), allocatable :: ij(:, :)
    !> Local corner nodes of each local cell, counter-clockwise from lower left.
    integer(ip), allocatable :: cell_nodes(:, :)
    !> Global 0-based index of each local cell (ascending).
    integer(i8), allocatable :: cell_gid(:)
    !> True for the cells this rank counts in global sums and writes (owner of corner 1).
    logical, allocatable :: cell_counted(:)
    !> For owned node n, the corner slots (4*(cell-1) + corner) of its up to 4 cells in the
    !> fixed order SW, SE, NW, NE; 0 where there is no cell. Fixed order: bitwise identical
    !> sums on any number of ranks.
    integer(ip), allocatable :: node_cells(:, :)
  contains
    procedure :: free => local_lattice_free
  end type local_lattice_t

contains

  !> Release all arrays.
  subroutine local_lattice_free(this)
    class(local_lattice_t), intent(inout) :: this
    if (allocated(this%gid)) deallocate(this%gid)
    if (allocated(this%ij)) deallocate(this%ij)
    if (allocated(this%cell_nodes)) deallocate(this%cell_nodes)
    if (allocated(this%cell_gid)) deallocate(this%cell_gid)
    if (allocated(this%cell_counted)) deallocate(this%cell_counted)
    if (allocated(this%node_cells)) deallocate(this%node_cells)
    this%n_owned = 0
    this%n_local = 0
    this%n_cells = 0
  end subroutine local_lattice_free
end module iem_local_lattice
