!> Recursive coordinate bisection of a grid's nodes: the (nx+1) x (ny+1) node index rectangle
!> is cut, across its longer side, into boxes holding as many nodes as their share of the
!> parts, until each part has its box. Every rank computes the same boxes from four numbers,
!> so the owner of any node is known without a partition array over the whole body.
module iem_rcb
  implicit none
  private
  public :: rcb_t

  !> The bisection tree and each part's box of node indices (i0, i1, j0, j1, inclusive).
  type :: rcb_t
    integer :: n_parts = 0, n_tree = 0
    !> Tree node k: its part (leaves, 0-based; -1 inside), the axis of its cut (1: i, 2: j),
    !> the first index on the high side, and its two children.
    integer, allocatable :: part(:), axis(:), cut(:), low(:), high(:)
    integer, allocatable :: box(:, :)
  contains
    procedure :: init => rcb_init
    procedure :: owner => rcb_owner
    procedure :: balanced => rcb_balanced
  end type rcb_t

contains

  !> Bisect the node rectangle [0, ni-1] x [0, nj-1] into n_parts boxes.
  subroutine rcb_init(this, ni, nj, n_parts)
    class(rcb_t), intent(inout) :: this
    integer, intent(in) :: ni, nj, n_parts
    integer :: k
    this%n_parts = n_parts
    this%n_tree = 0
    if (allocated(this%part)) deallocate(this%part, this%axis, this%cut, this%low, this%high, &
                                         this%box)
    allocate(this%part(2*n_parts), this%axis(2*n_parts), this%cut(2*n_parts), &
             this%low(2*n_parts), this%high(2*n_parts), this%box(4, 0:n_parts - 1))
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
        return
      end if
      nl = np/2
      if (i1 - i0 >= j1 - j0) then
        this%axis(node) = 1
        c = i0 + nint(real(i1 - i0 + 1)*real(nl)/real(np))
        this%cut(node) = c
        call split(i0, c - 1, j0, j1, p0, nl, a)
        call split(c, i1, j0, j1, p0 + nl, np - nl, b)
      else
        this%axis(node) = 2
        c = j0 + nint(real(j1 - j0 + 1)*real(nl)/real(np))
        this%cut(node) = c
        call split(i0, i1, j0, c - 1, p0, nl, a)
        call split(i0, i1, c, j1, p0 + nl, np - nl, b)
      end if
      this%low(node) = a
      this%high(node) = b
    end subroutine split
  end subroutine rcb_init

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
