!> One rank's part of the explicit lattice: owned nodes first (ascending global number), halo
!> nodes after (grouped by owning rank), and the cells touching owned nodes (ascending global
!> number), each with its corner nodes, material and open edges. The time loop reads only the
!> cell-to-node table and the materials; numbers and grid indices serve set-up and output.
!> The owned nodes' numbers and grid indices and the cells' numbers are kept as runs along
!> the grid rows (a few integers a row, none a node or cell), the halo nodes' one by one.
module iem_local_lattice
  use, intrinsic :: iso_fortran_env, only: int8
  use iem_kinds, only: wp, ip, i8
  use iem_cell_table, only: cell_table_t, max_chunk
  use iem_number_runs, only: number_runs_t
  implicit none
  private
  public :: local_lattice_t

  !> Local lattice of one rank.
  type :: local_lattice_t
    integer :: n_owned = 0, n_local = 0, n_cells = 0
    !> The owned nodes' global 0-based numbers in runs (iem_number_runs), each run along a
    !> grid row: the k-th node (from 0) of run r is at grid indices (run_i(r) + k, run_j(r)).
    !> Read them with node_gid, node_ij, local_of.
    type(number_runs_t) :: node_runs
    integer, allocatable :: run_i(:), run_j(:)
    !> The halo nodes' global numbers and grid indices (node n_owned + k is halo node k).
    integer(i8), allocatable :: halo_gid(:)
    integer, allocatable :: halo_ij(:, :)
    !> The grid's cell sizes: a node's reference coordinates are (i lx, j ly) (node_xy).
    real(wp) :: lx = 0.0_wp, ly = 0.0_wp
    !> The local cells in the force kernel's chunks, with their local corner nodes
    !> (counter-clockwise from lower left; iem_cell_table: listed only for the chunks whose
    !> node rows are not numbered consecutively). Read a cell's with cell_nodes or corners.
    type(cell_table_t) :: cells
    !> The local cells' global 0-based numbers in runs (at most one a grid row). Read them
    !> with cell_gid, cell_gids, cell_local_of.
    type(number_runs_t) :: cell_runs
    !> Each local cell's material (1..; kept only when the lattice is mixed, else every
    !> cell's is 1: read it with mat) and its open edges: bit q-1 set when edge q (bottom,
    !> right, top, left) lies on the boundary of the body.
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
    procedure :: node_ij => local_lattice_node_ij
    procedure :: node_gid => local_lattice_node_gid
    procedure :: owned_run => local_lattice_owned_run
    procedure :: owned_gids => local_lattice_owned_gids
    procedure :: local_of => local_lattice_local_of
    procedure :: cell_gid => local_lattice_cell_gid
    procedure :: cell_gids => local_lattice_cell_gids
    procedure :: cell_local_of => local_lattice_cell_local_of
    procedure :: mat => local_lattice_mat
    procedure :: cell_nodes => local_lattice_cell_nodes
    procedure :: corners => local_lattice_corners
    procedure :: first_corners => local_lattice_first_corners
    procedure :: cell_counted => local_lattice_cell_counted
    procedure :: n_counted => local_lattice_n_counted
    procedure :: counted_runs => local_lattice_counted_runs
    procedure :: edge_open => local_lattice_edge_open
    procedure :: free => local_lattice_free
  end type local_lattice_t

contains

  !> Reference coordinates (x, y) of local node l.
  pure function local_lattice_node_xy(this, l) result(xy)
    class(local_lattice_t), intent(in) :: this
    integer, intent(in) :: l
    real(wp) :: xy(2)
    integer :: ij(2)
    ij = this%node_ij(l)
    xy = [ij(1)*this%lx, ij(2)*this%ly]
  end function local_lattice_node_xy

  !> Grid indices (i, j) of local node l.
  pure function local_lattice_node_ij(this, l) result(ij)
    class(local_lattice_t), intent(in) :: this
    integer, intent(in) :: l
    integer :: ij(2), r
    if (l > this%n_owned) then
      ij = this%halo_ij(:, l - this%n_owned)
    else
      r = this%node_runs%run_of(l)
      ij = [this%run_i(r) + (l - this%node_runs%first(r)), this%run_j(r)]
    end if
  end function local_lattice_node_ij

  !> The owned nodes' run r (1..node_runs%n): its nodes l0..l1, the first one's grid indices
  !> (i0, j) and global number g0 (node l0 + k is at (i0 + k, j), numbered g0 + k), for loops
  !> over every owned node that need no lookup a node.
  pure subroutine local_lattice_owned_run(this, r, l0, l1, i0, j, g0)
    class(local_lattice_t), intent(in) :: this
    integer, intent(in) :: r
    integer, intent(out) :: l0, l1, i0, j
    integer(i8), intent(out) :: g0
    l0 = this%node_runs%first(r)
    l1 = this%node_runs%first(r + 1) - 1
    i0 = this%run_i(r)
    j = this%run_j(r)
    g0 = this%node_runs%gid(r)
  end subroutine local_lattice_owned_run

  !> Global 0-based number of local node l.
  pure integer(i8) function local_lattice_node_gid(this, l) result(g)
    class(local_lattice_t), intent(in) :: this
    integer, intent(in) :: l
    if (l > this%n_owned) then
      g = this%halo_gid(l - this%n_owned)
    else
      g = this%node_runs%number(l)
    end if
  end function local_lattice_node_gid

  !> Global numbers of the owned nodes 1..n_owned (ascending).
  pure function local_lattice_owned_gids(this) result(g)
    class(local_lattice_t), intent(in) :: this
    integer(i8), allocatable :: g(:)
    g = this%node_runs%numbers()
  end function local_lattice_owned_gids

  !> Local index of the owned node with global number g (0 when this rank does not own it).
  pure integer function local_lattice_local_of(this, g) result(l)
    class(local_lattice_t), intent(in) :: this
    integer(i8), intent(in) :: g
    l = this%node_runs%item_of(g)
  end function local_lattice_local_of

  !> Global 0-based number of local cell c.
  pure integer(i8) function local_lattice_cell_gid(this, c) result(g)
    class(local_lattice_t), intent(in) :: this
    integer, intent(in) :: c
    g = this%cell_runs%number(c)
  end function local_lattice_cell_gid

  !> Global numbers of the local cells 1..n_cells (ascending).
  pure function local_lattice_cell_gids(this) result(g)
    class(local_lattice_t), intent(in) :: this
    integer(i8), allocatable :: g(:)
    g = this%cell_runs%numbers()
  end function local_lattice_cell_gids

  !> Local index of the local cell with global number g (0 when it is not a local cell).
  pure integer function local_lattice_cell_local_of(this, g) result(c)
    class(local_lattice_t), intent(in) :: this
    integer(i8), intent(in) :: g
    c = this%cell_runs%item_of(g)
  end function local_lattice_cell_local_of

  !> Material (1..) of local cell c.
  pure integer function local_lattice_mat(this, c) result(m)
    class(local_lattice_t), intent(in) :: this
    integer, intent(in) :: c
    m = 1
    if (this%mixed) m = this%cell_mat(c)
  end function local_lattice_mat

  !> Local corner node q (1..4, counter-clockwise from the lower left) of local cell c.
  pure integer function local_lattice_cell_nodes(this, q, c) result(l)
    class(local_lattice_t), intent(in) :: this
    integer, intent(in) :: q, c
    l = this%cells%corner(q, c)
  end function local_lattice_cell_nodes

  !> The four local corner nodes of local cell c (counter-clockwise from the lower left).
  pure function local_lattice_corners(this, c) result(q)
    class(local_lattice_t), intent(in) :: this
    integer, intent(in) :: c
    integer :: q(4)
    q = this%cells%corners_of(c)
  end function local_lattice_corners

  !> The first corners fc(1:m) of the m cells of chunk j of cells (first cell cells%chunks(1,
  !> j)): the loops over all cells in cell order walk the chunks with it.
  pure subroutine local_lattice_first_corners(this, j, fc, m)
    class(local_lattice_t), intent(in) :: this
    integer, intent(in) :: j
    integer, intent(out) :: fc(:), m
    integer :: i
    m = this%cells%chunks(2, j)
    if (this%cells%chunks(3, j) == 1) then
      do i = 1, m
        fc(i) = this%cells%chunks(4, j) + i - 1
      end do
    else
      fc(1:m) = this%cells%corners(1, this%cells%chunks(6, j):this%cells%chunks(6, j) + m - 1)
    end if
  end subroutine local_lattice_first_corners

  !> True for the cells this rank counts in global sums and writes: those whose first corner
  !> it owns (each cell is counted by exactly one rank).
  pure logical function local_lattice_cell_counted(this, c) result(counted)
    class(local_lattice_t), intent(in) :: this
    integer, intent(in) :: c
    counted = this%cells%corner(1, c) <= this%n_owned
  end function local_lattice_cell_counted

  !> Number of cells this rank counts.
  pure integer function local_lattice_n_counted(this) result(n)
    class(local_lattice_t), intent(in) :: this
    integer :: j, m, fc(max_chunk)
    n = 0
    do j = 1, this%cells%n_chunks()
      call this%first_corners(j, fc, m)
      n = n + count(fc(1:m) <= this%n_owned)
    end do
  end function local_lattice_n_counted

  !> The cells this rank counts as runs(:, r) = (first local cell, its global number, cells
  !> in the run) of counted cells that follow each other in both numberings.
  pure function local_lattice_counted_runs(this) result(runs)
    class(local_lattice_t), intent(in) :: this
    integer(i8), allocatable :: runs(:, :)
    integer :: pass, nr, j, i, m, c, last_c, fc(max_chunk)
    integer(i8) :: g, last_g
    allocate(runs(3, 0))
    do pass = 1, 2
      nr = 0
      last_c = -1
      last_g = -1
      do j = 1, this%cells%n_chunks()
        call this%first_corners(j, fc, m)
        do i = 1, m
          if (fc(i) > this%n_owned) cycle
          c = this%cells%chunks(1, j) + i - 1
          g = this%cell_gid(c)
          if (c /= last_c + 1 .or. g /= last_g + 1) then
            nr = nr + 1
            if (pass == 2) runs(:, nr) = [int(c, i8), g, 0_i8]
          end if
          if (pass == 2) runs(3, nr) = runs(3, nr) + 1
          last_c = c
          last_g = g
        end do
      end do
      if (pass == 1) then
        deallocate(runs)
        allocate(runs(3, nr))
      end if
    end do
  end function local_lattice_counted_runs

  !> True when edge q (1 bottom, 2 right, 3 top, 4 left) of local cell c is on the boundary.
  pure logical function local_lattice_edge_open(this, c, q) result(open)
    class(local_lattice_t), intent(in) :: this
    integer, intent(in) :: c, q
    open = btest(this%cell_open(c), q - 1)
  end function local_lattice_edge_open

  !> Release all arrays.
  subroutine local_lattice_free(this)
    class(local_lattice_t), intent(inout) :: this
    call this%node_runs%free()
    if (allocated(this%run_i)) deallocate(this%run_i, this%run_j)
    if (allocated(this%halo_gid)) deallocate(this%halo_gid)
    if (allocated(this%halo_ij)) deallocate(this%halo_ij)
    call this%cells%free()
    call this%cell_runs%free()
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
