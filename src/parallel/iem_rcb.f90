!> Recursive coordinate bisection of a grid's nodes: the (nx+1) x (ny+1) node index rectangle
!> is cut (along its grid rows unless that makes long or thin parts: row_cut_ratio) into boxes
!> holding as many nodes as their share of the parts, until each part has its box. Every rank
!> computes the same boxes from four numbers, so the owner of any node is known without a
!> partition array over the whole body.
!> The weighted variant cuts the same way by the weights of the nodes that exist, held spread
!> over the ranks: one reduction of a histogram along the cut axis per tree node.
module iem_rcb
  use mpi_f08, only: MPI_Comm, MPI_Allreduce, MPI_IN_PLACE, MPI_SUM, MPI_INTEGER8
  use iem_kinds, only: i8, wp
  implicit none
  private
  public :: rcb_t

  !> A box is cut along a grid row (across j) unless it is at least row_cut_ratio times longer
  !> along i than along j, or it has fewer than row_cut_rows rows a part; then across its longer
  !> side. A cut across the rows costs each rank beside it a one-cell chunk of the force kernel
  !> a row, a cut along a row only routed corners in chunks of full length; but a cut along a
  !> row can only fall between rows, so a part of few long rows would be ill balanced
  !> (docs/architecture.md, "Partition and build").
  real, parameter, public :: row_cut_ratio = 8.0
  integer, parameter, public :: row_cut_rows = 32

  !> The bisection tree and each part's box of node indices (i0, i1, j0, j1, inclusive).
  type :: rcb_t
    integer :: n_parts = 0, n_tree = 0
    !> Tree node k: its part (leaves, 0-based; -1 inside), the axis of its cut (1: i, 2: j),
    !> the first index on the high side, and its two children.
    integer, allocatable :: part(:), axis(:), cut(:), low(:), high(:)
    integer, allocatable :: box(:, :)
    !> Each part's weight (0-based): the node count of its box (init) or the total weight of
    !> the points in it (init_weighted).
    integer(i8), allocatable :: weight(:)
  contains
    procedure :: init => rcb_init
    procedure :: init_weighted => rcb_init_weighted
    procedure :: owner => rcb_owner
    procedure :: balanced => rcb_balanced
  end type rcb_t

contains

  !> Bisect the node rectangle [0, ni-1] x [0, nj-1] into n_parts boxes (of node counts in
  !> proportion to share(0:n_parts-1) > 0 when given, else equal).
  subroutine rcb_init(this, ni, nj, n_parts, share)
    class(rcb_t), intent(inout) :: this
    integer, intent(in) :: ni, nj, n_parts
    real(wp), intent(in), optional :: share(0:)
    integer :: k
    this%n_parts = n_parts
    this%n_tree = 0
    call alloc_tree(this, n_parts)
    call split(0, ni - 1, 0, nj - 1, 0, n_parts, k)

  contains

    !> Tree node for the box [i0, i1] x [j0, j1] holding parts p0 .. p0 + np - 1.
    recursive subroutine split(i0, i1, j0, j1, p0, np, node)
      integer, intent(in) :: i0, i1, j0, j1, p0, np
      integer, intent(out) :: node
      integer :: nl, c, a, b
      this%n_tree = this%n_tree + 1
      node = this%n_tree
      this%part(node) = -1
      if (np == 1) then
        this%part(node) = p0
        this%box(:, p0) = [i0, i1, j0, j1]
        this%weight(p0) = int(max(0, i1 - i0 + 1), i8)*max(0, j1 - j0 + 1)
        return
      end if
      nl = np/2
      if (cuts_across_i(i0, i1, j0, j1, np)) then
        this%axis(node) = 1
        if (present(share)) then
          c = i0 + nint(real(i1 - i0 + 1, wp)*low_share(share, p0, np))
        else
          c = i0 + nint(real(i1 - i0 + 1)*real(nl)/real(np))
        end if
        this%cut(node) = c
        call split(i0, c - 1, j0, j1, p0, nl, a)
        call split(c, i1, j0, j1, p0 + nl, np - nl, b)
      else
        this%axis(node) = 2
        if (present(share)) then
          c = j0 + nint(real(j1 - j0 + 1, wp)*low_share(share, p0, np))
        else
          c = j0 + nint(real(j1 - j0 + 1)*real(nl)/real(np))
        end if
        this%cut(node) = c
        call split(i0, i1, j0, c - 1, p0, nl, a)
        call split(i0, i1, c, j1, p0 + nl, np - nl, b)
      end if
      this%low(node) = a
      this%high(node) = b
    end subroutine split
  end subroutine rcb_init

  !> Bisect the node rectangle [0, ni-1] x [0, nj-1] into n_parts boxes of about equal weight,
  !> the weights being those of the points ij(:, k) (node indices, 0-based) with w(k) >= 0 held
  !> by the ranks of comm (each point on one rank). Collective; every rank gets the same tree.
  !> Each cut is the one (first index of the high side) that gives the low side the weight
  !> nearest to its share of the parts (ties: the lower cut); total weight times n_parts must
  !> fit in integer(i8). With share(0:n_parts-1) > 0 the parts' weights are in proportion to
  !> it instead of equal (the low side's share of a cut is its parts' share of the box's).
  subroutine rcb_init_weighted(this, ni, nj, n_parts, ij, w, comm, share)
    class(rcb_t), intent(inout) :: this
    integer, intent(in) :: ni, nj, n_parts
    integer, intent(in) :: ij(:, :)
    integer(i8), intent(in) :: w(:)
    type(MPI_Comm), intent(in) :: comm
    real(wp), intent(in), optional :: share(0:)
    integer(i8) :: total(1)
    integer :: root
    this%n_parts = n_parts
    this%n_tree = 0
    call alloc_tree(this, n_parts)
    if (n_parts == 1) then
      total = sum(w, mask=w >= 0 .and. ij(1, :) >= 0 .and. ij(1, :) <= ni - 1 .and. &
                  ij(2, :) >= 0 .and. ij(2, :) <= nj - 1)
      call MPI_Allreduce(MPI_IN_PLACE, total, 1, MPI_INTEGER8, MPI_SUM, comm)
    else
      total = -1   ! the root's histogram gives it
    end if
    call split_w(0, ni - 1, 0, nj - 1, 0, n_parts, total(1), root)

  contains

    !> Tree node for the box [i0, i1] x [j0, j1] of weight wt (-1: not yet known) holding
    !> parts p0 .. p0 + np - 1. The same calls, in the same order, on every rank.
    recursive subroutine split_w(i0, i1, j0, j1, p0, np, wt, node)
      integer, intent(in) :: i0, i1, j0, j1, p0, np
      integer(i8), intent(in) :: wt
      integer, intent(out) :: node
      integer(i8), allocatable :: h(:)
      integer(i8) :: t, wl, d, best
      real(wp) :: f, e_best
      integer :: nl, ax, lo, hi, c, cc, a, b, q
      this%n_tree = this%n_tree + 1
      node = this%n_tree
      this%part(node) = -1
      if (np == 1) then
        this%part(node) = p0
        this%box(:, p0) = [i0, i1, j0, j1]
        this%weight(p0) = max(wt, 0_i8)
        return
      end if
      nl = np/2
      ! the axis row_cut_ratio picks (it spans one index only when the box is one node)
      ax = merge(1, 2, cuts_across_i(i0, i1, j0, j1, np))
      this%axis(node) = ax
      lo = merge(i0, j0, ax == 1)
      hi = merge(i1, j1, ax == 1)
      if (i1 < i0 .or. j1 < j0) then
        ! an empty box (more parts than nodes): no point can be in it, nor in its parts
        c = lo + 1
        t = 0
        wl = 0
      else
        ! the weight on each index line across the axis, summed over the ranks
        allocate(h(lo:hi))
        h = 0
        do q = 1, size(w)
          if (w(q) < 0) cycle
          if (ij(1, q) < i0 .or. ij(1, q) > i1 .or. ij(2, q) < j0 .or. ij(2, q) > j1) cycle
          h(ij(ax, q)) = h(ij(ax, q)) + w(q)
        end do
        call MPI_Allreduce(MPI_IN_PLACE, h, hi - lo + 1, MPI_INTEGER8, MPI_SUM, comm)
        t = sum(h)
        ! the cut in [lo + 1, hi] whose low side is nearest total*nl/np; a box one index wide
        ! along both axes keeps its node on the low side
        c = lo + 1
        wl = h(lo)
        d = wl
        if (present(share)) then
          ! (the same rule in real arithmetic: low side nearest f times the box's weight)
          f = low_share(share, p0, np)
          e_best = abs(real(wl, wp) - f*real(t, wp))
          do cc = lo + 2, hi
            d = d + h(cc - 1)
            if (abs(real(d, wp) - f*real(t, wp)) < e_best) then
              e_best = abs(real(d, wp) - f*real(t, wp))
              c = cc
              wl = d
            end if
          end do
        else
          best = abs(wl*np - t*nl)
          do cc = lo + 2, hi
            d = d + h(cc - 1)
            if (abs(d*np - t*nl) < best) then
              best = abs(d*np - t*nl)
              c = cc
              wl = d
            end if
          end do
        end if
        deallocate(h)
      end if
      this%cut(node) = c
      if (ax == 1) then
        call split_w(i0, c - 1, j0, j1, p0, nl, wl, a)
        call split_w(c, i1, j0, j1, p0 + nl, np - nl, t - wl, b)
      else
        call split_w(i0, i1, j0, c - 1, p0, nl, wl, a)
        call split_w(i0, i1, c, j1, p0 + nl, np - nl, t - wl, b)
      end if
      this%low(node) = a
      this%high(node) = b
    end subroutine split_w
  end subroutine rcb_init_weighted

  !> Whether the box [i0, i1] x [j0, j1] of np parts is cut across i (its cut line crossing
  !> every grid row), else across j.
  pure logical function cuts_across_i(i0, i1, j0, j1, np) result(yes)
    integer, intent(in) :: i0, i1, j0, j1, np
    if (j1 - j0 + 1 >= row_cut_rows*np) then
      yes = real(i1 - i0) >= row_cut_ratio*real(j1 - j0)
    else
      yes = i1 - i0 >= j1 - j0
    end if
  end function cuts_across_i

  !> The share of the low side of a box of the np parts p0 .. p0 + np - 1 cut in two (its
  !> np/2 parts' share of all np).
  pure real(wp) function low_share(share, p0, np) result(f)
    real(wp), intent(in) :: share(0:)
    integer, intent(in) :: p0, np
    f = sum(share(p0:p0 + np/2 - 1))/sum(share(p0:p0 + np - 1))
  end function low_share

  !> (Re)allocate the tree of n_parts leaves.
  subroutine alloc_tree(this, n_parts)
    class(rcb_t), intent(inout) :: this
    integer, intent(in) :: n_parts
    if (allocated(this%part)) deallocate(this%part, this%axis, this%cut, this%low, this%high, &
                                         this%box)
    if (allocated(this%weight)) deallocate(this%weight)
    allocate(this%part(2*n_parts), this%axis(2*n_parts), this%cut(2*n_parts), &
             this%low(2*n_parts), this%high(2*n_parts), this%box(4, 0:n_parts - 1), &
             this%weight(0:n_parts - 1))
  end subroutine alloc_tree

  !> The part (0-based) that owns node (i, j).
  pure integer function rcb_owner(this, i, j) result(p)
    class(rcb_t), intent(in) :: this
    integer, intent(in) :: i, j
    integer :: node
    node = 1
    do while (this%part(node) < 0)
      if (merge(i, j, this%axis(node) == 1) < this%cut(node)) then
        node = this%low(node)
      else
        node = this%high(node)
      end if
    end do
    p = this%part(node)
  end function rcb_owner

  !> True when every part's box holds at least min_nodes nodes.
  pure logical function rcb_balanced(this, min_nodes) result(ok)
    class(rcb_t), intent(in) :: this
    integer, intent(in) :: min_nodes
    integer :: p
    ok = .true.
    do p = 0, this%n_parts - 1
      if ((this%box(2, p) - this%box(1, p) + 1) < 1 .or. &
          (this%box(4, p) - this%box(3, p) + 1) < 1) then
        ok = .false.
      else if (int(this%box(2, p) - this%box(1, p) + 1, kind(1_8))* &
               (this%box(4, p) - this%box(3, p) + 1) < min_nodes) then
        ok = .false.
      end if
    end do
  end function rcb_balanced
end module iem_rcb
