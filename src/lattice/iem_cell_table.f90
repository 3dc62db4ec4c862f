!> A rank's cells as the force kernel walks them: chunks of up to 64 consecutive cells of a
!> grid row (each sharing its left edge with the right edge of the one before), with the
!> corner nodes of each cell. A chunk whose bottom and top node rows are each numbered
!> consecutively (the common case: every chunk of a rank without halo nodes) keeps only its
!> first bottom and top nodes, from which its cells' corners follow; only the other chunks
!> list their cells' corners. So the table costs a few integers a chunk, not 16 bytes a cell.
module iem_cell_table
  use iem_kinds, only: i8
  use iem_cell_laws, only: chunk
  use iem_sort, only: sort_i8
  implicit none
  private
  public :: cell_table_t, cell_table, cell_chunks

  !> The most cells a chunk holds (the force kernel's chunk).
  integer, parameter, public :: max_chunk = chunk

  !> Cells in chunks: chunk j holds the cells chunks(1, j) .. chunks(1, j) + chunks(2, j) - 1;
  !> chunks(3, j) = 1 when its node rows are consecutive (cell i of it, from 1, has the corners
  !> b0 + i - 1, b0 + i, t0 + i, t0 + i - 1 counter-clockwise from the lower left, with b0 =
  !> chunks(4, j) and t0 = chunks(5, j), the first cell's lower-left and upper-left nodes),
  !> else 0 and its cells' corners are the columns corners(:, chunks(6, j) + i - 1).
  type :: cell_table_t
    !> Number of cells the table's cell numbers range over (a subset of chunks keeps it).
    integer :: n_cells = 0
    integer, allocatable :: chunks(:, :)
    integer, allocatable :: corners(:, :)
    !> block(k): the first chunk that holds a cell of 64 k + 1 .. 64 k + 64 (chunk_at).
    integer, allocatable :: block(:)
    !> below(:, j): the chunks before chunk j whose top node rows hold nodes and edges of its
    !> bottom row (the rows of all three numbered consecutively): p, the first one that does
    !> (0: none), and q, the one that goes on from p's end (0: none, or p's holds the rest).
    !> The force kernel takes those edges from them (link_rows).
    integer, allocatable :: below(:, :)
  contains
    procedure :: n_chunks => cell_table_n_chunks
    procedure :: chunk_at => cell_table_chunk_at
    procedure :: corners_of => cell_table_corners_of
    procedure :: corner => cell_table_corner
    procedure :: chunk_corners => cell_table_chunk_corners
    procedure :: subset => cell_table_subset
    procedure :: free => cell_table_free
  end type cell_table_t

contains

  !> The table of the cells cell_nodes(4, :) (corners counter-clockwise from the lower left):
  !> their chunks (cell_chunks, with kind: a chunk also ends where the kind changes) and the
  !> corners of the chunks whose node rows are not consecutive.
  pure function cell_table(cell_nodes, kind) result(t)
    integer, intent(in) :: cell_nodes(:, :)
    integer, intent(in), optional :: kind(:)
    type(cell_table_t) :: t
    integer, allocatable :: plan(:, :)
    integer :: j, n, c0, m
    allocate(plan, source=cell_chunks(cell_nodes, kind))
    t%n_cells = size(cell_nodes, 2)
    allocate(t%chunks(6, size(plan, 2)))
    t%chunks(1:5, :) = plan
    n = 0
    do j = 1, size(plan, 2)
      t%chunks(6, j) = 0
      if (plan(3, j) == 1) cycle
      t%chunks(6, j) = n + 1
      n = n + plan(2, j)
    end do
    allocate(t%corners(4, n))
    do j = 1, size(plan, 2)
      if (plan(3, j) == 1) cycle
      c0 = plan(1, j)
      m = plan(2, j)
      t%corners(:, t%chunks(6, j):t%chunks(6, j) + m - 1) = cell_nodes(:, c0:c0 + m - 1)
    end do
    call make_blocks(t)
    call link_rows(t)
  end function cell_table

  !> The chunks of a cell list: plan(:, j) = (first cell, number of cells, 1 when the chunk's
  !> bottom and top node rows are each numbered consecutively, else 0, the first cell's
  !> bottom-left and top-left nodes). A chunk holds up to 64 consecutive cells each sharing
  !> its left edge with the right edge of the one before (a run of a grid row), so holes and a
  !> rank's row ends end chunks. With kind (one a cell), a chunk also ends where the kind
  !> changes.
  pure function cell_chunks(cell_nodes, kind) result(plan)
    integer, intent(in) :: cell_nodes(:, :)
    integer, intent(in), optional :: kind(:)
    integer, allocatable :: plan(:, :)
    integer :: nc, c0, m, n, pass
    nc = size(cell_nodes, 2)
    ! first count the chunks, then fill them
    do pass = 1, 2
      n = 0
      c0 = 1
      do while (c0 <= nc)
        m = 1
        do while (m < chunk .and. c0 + m <= nc)
          if (cell_nodes(1, c0 + m) /= cell_nodes(2, c0 + m - 1) .or. &
              cell_nodes(4, c0 + m) /= cell_nodes(3, c0 + m - 1)) exit
          if (present(kind)) then
            if (kind(c0 + m) /= kind(c0)) exit
          end if
          m = m + 1
        end do
        n = n + 1
        if (pass == 2) then
          plan(:, n) = [c0, m, 0, cell_nodes(1, c0), cell_nodes(4, c0)]
          ! consecutive node rows: each cell's right corners follow its left ones
          if (all(cell_nodes(2, c0:c0 + m - 1) - cell_nodes(1, c0:c0 + m - 1) == 1) .and. &
              all(cell_nodes(3, c0:c0 + m - 1) - cell_nodes(4, c0:c0 + m - 1) == 1)) plan(3, n) = 1
        end if
        c0 = c0 + m
      end do
      if (pass == 1) allocate(plan(5, n))
    end do
  end function cell_chunks

  !> Number of chunks.
  pure integer function cell_table_n_chunks(this) result(n)
    class(cell_table_t), intent(in) :: this
    n = 0
    if (allocated(this%chunks)) n = size(this%chunks, 2)
  end function cell_table_n_chunks

  !> The chunk that holds cell c (0 when no chunk of the table holds it).
  pure integer function cell_table_chunk_at(this, c) result(j)
    class(cell_table_t), intent(in) :: this
    integer, intent(in) :: c
    integer :: nj
    j = 0
    nj = this%n_chunks()
    if (c < 1 .or. c > this%n_cells .or. nj == 0) return
    j = this%block((c - 1)/chunk)
    do while (j <= nj)
      if (this%chunks(1, j) > c) exit
      if (c < this%chunks(1, j) + this%chunks(2, j)) return
      j = j + 1
    end do
    j = 0
  end function cell_table_chunk_at

  !> The four corners of cell c (counter-clockwise from the lower left; zeros when the table
  !> does not hold it).
  pure function cell_table_corners_of(this, c) result(q)
    class(cell_table_t), intent(in) :: this
    integer, intent(in) :: c
    integer :: q(4), j, k
    q = 0
    j = this%chunk_at(c)
    if (j == 0) return
    do k = 1, 4
      q(k) = chunk_corner(this, j, c - this%chunks(1, j), k)
    end do
  end function cell_table_corners_of

  !> Corner k (1..4, counter-clockwise from the lower left) of cell c (0 when the table does
  !> not hold it), without forming the other three.
  pure integer function cell_table_corner(this, k, c) result(n)
    class(cell_table_t), intent(in) :: this
    integer, intent(in) :: k, c
    integer :: j
    n = 0
    j = this%chunk_at(c)
    if (j == 0) return
    n = chunk_corner(this, j, c - this%chunks(1, j), k)
  end function cell_table_corner

  !> Corner k of the cell after the first i cells of chunk j: from the chunk's first bottom
  !> and top nodes when its node rows are numbered consecutively, else from its list.
  pure integer function chunk_corner(this, j, i, k) result(n)
    type(cell_table_t), intent(in) :: this
    integer, intent(in) :: j, i, k
    if (this%chunks(3, j) == 1) then
      select case (k)
      case (1)
        n = this%chunks(4, j) + i
      case (2)
        n = this%chunks(4, j) + i + 1
      case (3)
        n = this%chunks(5, j) + i + 1
      case default
        n = this%chunks(5, j) + i
      end select
    else
      n = this%corners(k, this%chunks(6, j) + i)
    end if
  end function chunk_corner

  !> The corners q(:, 1:m) of the m cells of chunk j.
  pure subroutine cell_table_chunk_corners(this, j, q, m)
    class(cell_table_t), intent(in) :: this
    integer, intent(in) :: j
    integer, intent(out) :: q(:, :), m
    integer :: i, b0, t0
    m = this%chunks(2, j)
    if (this%chunks(3, j) == 1) then
      b0 = this%chunks(4, j)
      t0 = this%chunks(5, j)
      do i = 1, m
        q(:, i) = [b0 + i - 1, b0 + i, t0 + i, t0 + i - 1]
      end do
    else
      q(:, 1:m) = this%corners(:, this%chunks(6, j):this%chunks(6, j) + m - 1)
    end if
  end subroutine cell_table_chunk_corners

  !> The table of the chunks j of this with take(j), in their order (the same cell numbers).
  pure function cell_table_subset(this, take) result(t)
    class(cell_table_t), intent(in) :: this
    logical, intent(in) :: take(:)
    type(cell_table_t) :: t
    integer :: j, k, n, m
    t%n_cells = this%n_cells
    allocate(t%chunks(6, count(take)))
    n = 0
    k = 0
    do j = 1, this%n_chunks()
      if (.not. take(j)) cycle
      k = k + 1
      t%chunks(:, k) = this%chunks(:, j)
      if (this%chunks(3, j) == 1) cycle
      t%chunks(6, k) = n + 1
      n = n + this%chunks(2, j)
    end do
    allocate(t%corners(4, n))
    k = 0
    do j = 1, this%n_chunks()
      if (.not. take(j)) cycle
      k = k + 1
      if (this%chunks(3, j) == 1) cycle
      m = this%chunks(2, j)
      t%corners(:, t%chunks(6, k):t%chunks(6, k) + m - 1) = &
        this%corners(:, this%chunks(6, j):this%chunks(6, j) + m - 1)
    end do
    call make_blocks(t)
    call link_rows(t)
  end function cell_table_subset

  !> Release the table.
  subroutine cell_table_free(this)
    class(cell_table_t), intent(inout) :: this
    if (allocated(this%chunks)) deallocate(this%chunks)
    if (allocated(this%corners)) deallocate(this%corners)
    if (allocated(this%block)) deallocate(this%block)
    if (allocated(this%below)) deallocate(this%below)
    this%n_cells = 0
  end subroutine cell_table_free

  !> block(k): the first chunk holding a cell of 64 k + 1 .. 64 k + 64, or the first chunk
  !> after them (chunks in ascending cell order; a subset may skip cells).
  pure subroutine make_blocks(t)
    type(cell_table_t), intent(inout) :: t
    integer :: j, k, nb
    nb = max(0, (t%n_cells - 1)/chunk) + 1
    allocate(t%block(0:nb - 1))
    j = 1
    do k = 0, nb - 1
      ! the first chunk whose last cell is at or past the block's first cell
      do while (j <= t%n_chunks())
        if (t%chunks(1, j) + t%chunks(2, j) - 1 >= k*chunk + 1) exit
        j = j + 1
      end do
      t%block(k) = j
    end do
  end subroutine make_blocks

  !> below (cell_table_t's): for each chunk whose node rows are consecutive, the one or two
  !> such chunks before it whose top rows hold edges of its bottom row: the first one that
  !> does, and the one beside it when that holds more of them.
  pure subroutine link_rows(t)
    type(cell_table_t), intent(inout) :: t
    integer(i8), allocatable :: key(:)
    integer :: nj, n, j, lo, hi, mid, p, q, b, m
    nj = t%n_chunks()
    allocate(t%below(2, nj))
    t%below = 0
    ! the consecutive chunks by their top rows' first nodes (t0 * 2^31 + chunk)
    n = count(t%chunks(3, :) == 1)
    allocate(key(n))
    n = 0
    do j = 1, nj
      if (t%chunks(3, j) /= 1) cycle
      n = n + 1
      key(n) = int(t%chunks(5, j), i8)*2_i8**31 + j
    end do
    call sort_i8(key)
    do j = 1, nj
      if (t%chunks(3, j) /= 1) cycle
      b = t%chunks(4, j)
      m = t%chunks(2, j)
      ! the last chunk whose top row starts at or before node b
      lo = 0
      hi = n
      do while (lo < hi)
        mid = (lo + hi + 1)/2
        if (key(mid)/2_i8**31 <= b) then
          lo = mid
        else
          hi = mid - 1
        end if
      end do
      ! the first top row that holds an edge of nodes b .. b + m (their row's: a top row that
      ! holds one of them is of the same grid row): it, or the next one
      if (lo > 0) then
        if (top_end(lo) <= b) lo = lo + 1
      else
        lo = 1
      end if
      if (lo > n) cycle
      if (top_first(lo) >= b + m) cycle
      p = chunk_of_key(lo)
      if (p >= j) cycle
      t%below(1, j) = p
      ! the top row that goes on from p's end, when the bottom row goes on past it
      if (top_end(lo) >= b + m .or. lo == n) cycle
      if (top_first(lo + 1) /= top_end(lo)) cycle
      q = chunk_of_key(lo + 1)
      if (q < j) t%below(2, j) = q
    end do
  contains

    !> The first node of the top row of the chunk of key(i).
    pure integer function top_first(i)
      integer, intent(in) :: i
      top_first = int(key(i)/2_i8**31)
    end function top_first

    !> The last node of the top row of the chunk of key(i).
    pure integer function top_end(i)
      integer, intent(in) :: i
      top_end = top_first(i) + t%chunks(2, chunk_of_key(i))
    end function top_end

    !> The chunk of key(i).
    pure integer function chunk_of_key(i)
      integer, intent(in) :: i
      chunk_of_key = int(mod(key(i), 2_i8**31))
    end function chunk_of_key
  end subroutine link_rows
end module iem_cell_table
