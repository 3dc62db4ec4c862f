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
!> With a width, the boundary cells are those a few cells from the halo nodes (RK4's
!> wavefront's strips, iem_stage_wave), and the boundary chunks too take the plain path,
!> adding to their halo nodes (forces not used) and to the nodes of D whose cells are all
!> boundary cells (early), which they alone reach, and setting aside their other corners.
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
    !> (a halo node, whose force is not used); for an interior chunk with corners in D (and,
    !> with a width, a boundary chunk with corners in D that are not early), their number n,
    !> then n pairs (4*(i - 1) + q: corner q of its cell i; its side slot).
    integer, allocatable :: route(:)
    !> The owned nodes of D (ascending); node d's slots are 4(d-1)+1 .. 4(d-1)+d_cells(d),
    !> one for each of its cells, in cell order.
    integer, allocatable :: d_node(:), d_cells(:)
    !> The side slots: the corner forces (x, y) of the cells of D's owned nodes.
    real(wp), allocatable :: side(:, :)
    !> The nodes of D whose cells are all boundary cells (ascending positions in d_node):
    !> their forces are complete after the boundary chunks alone (with a width, added to the
    !> forces by the boundary chunks: no slots).
    integer, allocatable :: early(:)
  contains
    procedure :: init => split_init
    procedure :: sum_side => split_sum_side
    procedure :: sum_side_of => split_sum_side_of
  end type cell_split_t

contains

  !> Split the cells of a rank whose nodes 1..n_owned are owned and n_owned+1..n_local halo
  !> nodes; inactive (nothing split) without halo nodes. The boundary cells are those with a
  !> corner at most width - 1 cells from a halo node (default width 1: a halo corner; RK4's
  !> wavefront on ranks with halo nodes takes wider strips, iem_stage_wave).
  subroutine split_init(this, cells, n_owned, n_local, width)
    class(cell_split_t), intent(inout) :: this
    type(cell_table_t), intent(in) :: cells
    integer, intent(in) :: n_owned, n_local
    integer, intent(in), optional :: width
    logical, allocatable :: bd(:), is_bd(:), near(:)
    logical :: plain
    integer, allocatable :: plan(:, :), cnt(:), cell_nodes(:, :), kind(:), lvl(:), n_bd_of(:), &
                            pos(:), n_all(:)
    type(cell_table_t) :: split
    integer(i8), allocatable :: dl(:)
    integer :: nc, c, q, j, k, n, nd, na, n_in, n_bd, n_route, at, c0, m, d

    this%active = n_local > n_owned
    if (allocated(this%at_in)) deallocate(this%at_in, this%at_bd, this%route, this%d_node, &
                                          this%d_cells, this%side, this%early)
    call this%cells_in%free()
    call this%cells_bd%free()
    if (.not. this%active) return
    ! every cell's corners, for the making of the split only
    nc = cells%n_cells
    allocate(cell_nodes(4, nc))
    do j = 1, cells%n_chunks()
      call cells%chunk_corners(j, cell_nodes(:, cells%chunks(1, j):), m)
    end do
    ! each node's distance in cells from the halo nodes, up to width - 1
    allocate(lvl(n_local), bd(nc))
    lvl(1:n_owned) = huge(1)
    lvl(n_owned + 1:n_local) = 0
    do k = 1, merge(width, 1, present(width)) - 1
      do c = 1, nc
        if (minval(lvl(cell_nodes(:, c))) /= k - 1) cycle
        do q = 1, 4
          lvl(cell_nodes(q, c)) = min(lvl(cell_nodes(q, c)), k)
        end do
      end do
    end do
    do c = 1, nc
      bd(c) = minval(lvl(cell_nodes(:, c))) < huge(1)
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
    ! each local node's position in D's list (0: not in D)
    allocate(pos(n_local))
    pos = 0
    do k = 1, na
      pos(dl(k)) = k
    end do
    allocate(this%d_node(nd), this%d_cells(nd), this%side(2, 4*nd))
    this%d_node = int(dl(1:nd))
    this%d_cells = 0
    this%side = 0.0_wp
    ! the nodes of D with boundary cells only (early): with a width, the boundary chunks add
    ! their forces to them as the interior chunks do to theirs
    allocate(n_bd_of(nd), n_all(nd))
    n_bd_of = 0
    n_all = 0
    do c = 1, nc
      do q = 1, 4
        d = find(cell_nodes(q, c))
        if (d == 0 .or. d > nd) cycle
        n_all(d) = n_all(d) + 1
        if (bd(c)) n_bd_of(d) = n_bd_of(d) + 1
      end do
    end do
    this%early = pack([(d, d = 1, nd)], n_bd_of == n_all)
    plain = present(width)
    ! the chunks, of one kind each, in cell order: interior cells and boundary cells. A
    ! boundary chunk is routed corner by corner (with a width: takes the plain path but for
    ! its corners in D that are not early, as an interior chunk); an interior chunk with
    ! corners in D takes the plain path but for those corners, which it sets aside into their
    ! side slots
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
      if (bd(c0) .and. plain) then
        n_bd = n_bd + 1
        k = count_in_d(c0, m)
        if (k > 0) n_route = n_route + 1 + 2*k
      else if (bd(c0)) then
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
      if (bd(c0) .and. plain) then
        n_bd = n_bd + 1
        call set_aside(this%at_bd(n_bd))
      else if (bd(c0)) then
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
        ! (an interior cell has no halo corner, nor an early one)
        call set_aside(this%at_in(n_in))
      end if
    end do
    this%d_cells = cnt
    this%cells_in = split%subset(.not. is_bd)
    this%cells_bd = split%subset(is_bd)
  contains

    !> The chunk of the cells c0 .. c0 + m - 1 on the plain path: its corners in D that are not
    !> early set aside into their slots (at_j: minus where their list starts in route; 0:
    !> none).
    subroutine set_aside(at_j)
      integer, intent(out) :: at_j
      integer :: kk, cc, qq, dd
      at_j = 0
      kk = count_in_d(c0, m)
      if (kk == 0) return
      at_j = -at
      this%route(at) = kk
      at = at + 1
      do cc = c0, c0 + m - 1
        do qq = 1, 4
          dd = find(cell_nodes(qq, cc))
          if (.not. aside(dd)) cycle
          cnt(dd) = cnt(dd) + 1
          this%route(at) = 4*(cc - c0) + qq
          this%route(at + 1) = 4*(dd - 1) + cnt(dd)
          at = at + 2
        end do
      end do
    end subroutine set_aside

    !> Whether a corner at position d of D's list is set aside on the plain path (an owned
    !> node of D that is not early).
    pure logical function aside(d)
      integer, intent(in) :: d
      aside = d > 0 .and. d <= nd
      if (aside) aside = n_bd_of(d) < n_all(d)
    end function aside

    !> The position of node l in D's list dl(1:na) (0: not in D).
    pure integer function find(l)
      integer, intent(in) :: l
      find = pos(l)
    end function find

    !> The corners set aside of the cells c0 .. c0 + m - 1 (aside).
    pure integer function count_in_d(c0, m) result(n)
      integer, intent(in) :: c0, m
      integer :: cc, qq
      n = 0
      do cc = c0, c0 + m - 1
        if (.not. near(cc)) cycle
        do qq = 1, 4
          if (aside(find(cell_nodes(qq, cc)))) n = n + 1
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
    integer :: d
    do d = 1, size(this%d_node)
      call add_slots(this, f, d)
    end do
  end subroutine split_sum_side

  !> The forces of D's owned nodes d_node(which) in f: each one's side slots added to it in
  !> cell order (once its cells are all evaluated).
  pure subroutine split_sum_side_of(this, f, which)
    class(cell_split_t), intent(in) :: this
    real(wp), intent(inout), contiguous :: f(:, :)
    integer, intent(in) :: which(:)
    integer :: k
    do k = 1, size(which)
      call add_slots(this, f, which(k))
    end do
  end subroutine split_sum_side_of

  !> Node d_node(d)'s side slots added to its force in f, in cell order.
  pure subroutine add_slots(this, f, d)
    type(cell_split_t), intent(in) :: this
    real(wp), intent(inout) :: f(:, :)
    integer, intent(in) :: d
    integer :: n, s, s0
    n = this%d_node(d)
    s0 = 4*(d - 1)
    do s = s0 + 1, s0 + this%d_cells(d)
      f(1, n) = f(1, n) + this%side(1, s)
      f(2, n) = f(2, n) + this%side(2, s)
    end do
  end subroutine add_slots
end module iem_cell_split
