!> The split of a rank's cells that lets the force evaluation overlap the halo exchange
!> (docs/architecture.md, "Overlapping the halo exchange"): the boundary cells (those with a
!> halo corner) and the interior cells go in separate chunks, so the interior chunks can be
!> evaluated while the halo values are on their way and the boundary chunks once they are in.
!> The sums stay bitwise those of one pass in cell order: a node that is a corner of a
!> boundary cell (a node of D) gets each of its cells' corner forces in a side slot of its
!> own, ordered by cell, and the slots are summed in that order after both phases; every
!> other node has interior cells only, whose forces are added to it in cell order as before.
!> The boundary chunks are routed corner by corner; the interior chunks keep the kernel's plain
!> path, and those with corners in D set them aside: each such corner force goes to its side
!> slot, and the chunk adds +0 for it to the node's force (which is +0 until the slots' sum).
module iem_cell_split
  use iem_kinds, only: wp, i8
  use iem_sort, only: sort_i8
  use iem_cell_table, only: cell_table_t, cell_table
  implicit none
  private
  public :: cell_split_t

  !> The split of one rank's cells (made once for its lattice); compact: storage only for the
  !> chunks that touch D and for the owned nodes of D.
  type :: cell_split_t
    !> Whether the rank has halo nodes (else nothing is split and nothing is allocated).
    logical :: active = .false.
    !> The interior and the boundary chunks (iem_cell_table's tables), each in cell order.
    type(cell_table_t) :: cells_in, cells_bd
    !> Per chunk of cells_bd: where its routes start in route; per chunk of cells_in: minus
    !> where its list of the corners it sets aside starts in route (0: none). iem_cell_kernel's
    !> cell_forces' route_at.
    integer, allocatable :: at_in(:), at_bd(:)
    !> Per corner of a boundary chunk's cells: 0 added to f, r > 0 side slot r, < 0 dropped
    !> (a halo node, whose force is not used); for an interior chunk with corners in D, their
    !> number n, then n pairs (4*(i - 1) + q: corner q of its cell i; its side slot).
    integer, allocatable :: route(:)
    !> The owned nodes of D (ascending); node d's slots are 4(d-1)+1 .. 4(d-1)+d_cells(d),
    !> one for each of its cells, in cell order.
    integer, allocatable :: d_node(:), d_cells(:)
    !> The side slots: the corner forces (x, y) of the cells of D's owned nodes.
    real(wp), allocatable :: side(:, :)
  contains
    procedure :: init => split_init
    procedure :: sum_side => split_sum_side
  end type cell_split_t

contains

  !> Split the cells of a rank whose nodes 1..n_owned are owned and n_owned+1..n_local halo
  !> nodes; inactive (nothing split) without halo nodes.
  subroutine split_init(this, cells, n_owned, n_local)
    class(cell_split_t), intent(inout) :: this
    type(cell_table_t), intent(in) :: cells
    integer, intent(in) :: n_owned, n_local
    logical, allocatable :: bd(:), is_bd(:), near(:)
    integer, allocatable :: plan(:, :), cnt(:), cell_nodes(:, :), kind(:)
    type(cell_table_t) :: split
    integer(i8), allocatable :: dl(:)
    integer :: nc, c, q, j, k, n, nd, na, n_in, n_bd, n_route, at, c0, m, d

    this%active = n_local > n_owned
    if (allocated(this%at_in)) deallocate(this%at_in, this%at_bd, this%route, this%d_node, &
                                          this%d_cells, this%side)
    call this%cells_in%free()
    call this%cells_bd%free()
    if (.not. this%active) return
    ! every cell's corners, for the making of the split only
    nc = cells%n_cells
    allocate(cell_nodes(4, nc))
    do j = 1, cells%n_chunks()
      call cells%chunk_corners(j, cell_nodes(:, cells%chunks(1, j):), m)
    end do
    allocate(bd(nc))
    do c = 1, nc
      bd(c) = any(cell_nodes(:, c) > n_owned)
    end do
    ! D: the corners of the boundary cells, ascending and unique (owned ones first)
    allocate(dl(4*count(bd)))
    n = 0
    do c = 1, nc
      if (.not. bd(c)) cycle
      dl(n + 1:n + 4) = int(cell_nodes(:, c), i8)
      n = n + 4
    end do
    call sort_i8(dl)
    na = 0
    do k = 1, n
      if (na > 0) then
        if (dl(k) == dl(na)) cycle
      end if
      na = na + 1
      dl(na) = dl(k)
    end do
    nd = 0
    do k = 1, na
      if (dl(k) <= n_owned) nd = k
    end do
    allocate(this%d_node(nd), this%d_cells(nd), this%side(2, 4*nd))
    this%d_node = int(dl(1:nd))
    this%d_cells = 0
    this%side = 0.0_wp
    ! the chunks, of one kind each, in cell order: interior cells and boundary cells. A
    ! boundary chunk is routed corner by corner; an interior chunk with corners in D takes the
    ! plain path but for those corners, which it sets aside into their side slots
    allocate(near(nc), kind(nc))
    do c = 1, nc
      near(c) = touches(c)
    end do
    kind = merge(2, 0, bd)
    split = cell_table(cell_nodes, kind)
    plan = split%chunks
    n_in = 0
    n_bd = 0
    n_route = 0
    do j = 1, size(plan, 2)
      c0 = plan(1, j)
      m = plan(2, j)
      if (bd(c0)) then
        n_bd = n_bd + 1
        n_route = n_route + 4*m
      else
        n_in = n_in + 1
        k = count_in_d(c0, m)
        if (k > 0) n_route = n_route + 1 + 2*k
      end if
    end do
    allocate(this%at_in(n_in), this%at_bd(n_bd), this%route(n_route), cnt(nd), &
             is_bd(size(plan, 2)))
    cnt = 0
    n_in = 0
    n_bd = 0
    at = 1
    do j = 1, size(plan, 2)
      c0 = plan(1, j)
      m = plan(2, j)
      is_bd(j) = bd(c0)
      if (bd(c0)) then
        ! (every corner of a boundary cell is in D, or a halo node) routed, cells in ascending
        ! order, so each node's slots come in cell order
        n_bd = n_bd + 1
        this%at_bd(n_bd) = at
        do c = c0, c0 + m - 1
          do q = 1, 4
            d = find(cell_nodes(q, c))
            k = at + 4*(c - c0) + q - 1
            if (d == 0) then
              this%route(k) = 0
            else if (d > nd) then
              this%route(k) = -1
            else
              cnt(d) = cnt(d) + 1
              this%route(k) = 4*(d - 1) + cnt(d)
            end if
          end do
        end do
        at = at + 4*m
      else
        n_in = n_in + 1
        this%at_in(n_in) = 0
        k = count_in_d(c0, m)
        if (k == 0) cycle
        ! the corners in D (owned: an interior cell has no halo corner), set aside
        this%at_in(n_in) = -at
        this%route(at) = k
        at = at + 1
        do c = c0, c0 + m - 1
          do q = 1, 4
            d = find(cell_nodes(q, c))
            if (d == 0) cycle
            cnt(d) = cnt(d) + 1
            this%route(at) = 4*(c - c0) + q
            this%route(at + 1) = 4*(d - 1) + cnt(d)
            at = at + 2
          end do
        end do
      end if
    end do
    this%d_cells = cnt
    this%cells_in = split%subset(.not. is_bd)
    this%cells_bd = split%subset(is_bd)
  contains

    !> The position of node l in D's list dl(1:na) (0: not in D).
    pure integer function find(l)
      integer, intent(in) :: l
      integer :: lo, hi, mid
      find = 0
      lo = 1
      hi = na
      do while (lo <= hi)
        mid = (lo + hi)/2
        if (dl(mid) == l) then
          find = mid
          return
        else if (dl(mid) < l) then
          lo = mid + 1
        else
          hi = mid - 1
        end if
      end do
    end function find

    !> The corners in D of the cells c0 .. c0 + m - 1.
    pure integer function count_in_d(c0, m) result(n)
      integer, intent(in) :: c0, m
      integer :: cc, qq
      n = 0
      do cc = c0, c0 + m - 1
        if (.not. near(cc)) cycle
        do qq = 1, 4
          if (find(cell_nodes(qq, cc)) > 0) n = n + 1
        end do
      end do
    end function count_in_d

    !> Whether cell c has a corner in D.
    pure logical function touches(c)
      integer, intent(in) :: c
      integer :: qq
      touches = .false.
      do qq = 1, 4
        if (find(cell_nodes(qq, c)) > 0) then
          touches = .true.
          return
        end if
      end do
    end function touches
  end subroutine split_init

  !> The forces of D's owned nodes in f: each node's side slots added to it in cell order
  !> (after both phases of an evaluation; f holds what the sum starts from, zeros).
  pure subroutine split_sum_side(this, f)
    class(cell_split_t), intent(in) :: this
    real(wp), intent(inout), contiguous :: f(:, :)
    integer :: d, n, s, s0
    do d = 1, size(this%d_node)
      n = this%d_node(d)
      s0 = 4*(d - 1)
      do s = s0 + 1, s0 + this%d_cells(d)
        f(1, n) = f(1, n) + this%side(1, s)
        f(2, n) = f(2, n) + this%side(2, s)
      end do
    end do
  end subroutine split_sum_side
end module iem_cell_split
