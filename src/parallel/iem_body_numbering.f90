!> The numbering of a body cut from the grid, done in row strips so that no rank holds a map
!> of the whole grid (docs/architecture.md, "Set-up"). Rank s of P classifies the cell rows
!> [s ny / P, (s+1) ny / P) of its strip (and one row around); the ranks share the number of
!> cells and nodes of every row (one number a row), so that the number of a cell or node is
!> its row's first number plus the cells or nodes before it in its row. The strip also gives
!> the errors that need the whole body (the same on every rank), the nodes that the weighted
!> bisection balances, and the counts left of a column that a rank's window needs.
module iem_body_numbering
  use, intrinsic :: iso_fortran_env, only: int8
  use mpi_f08, only: MPI_Comm, MPI_Comm_rank, MPI_Comm_size, MPI_Allreduce, MPI_Allgatherv, &
                     MPI_Alltoallv, MPI_Bcast, MPI_IN_PLACE, MPI_SUM, MPI_MIN, MPI_INTEGER, &
                     MPI_INTEGER8, MPI_CHARACTER
  use iem_kinds, only: wp, i8
  use iem_body, only: body_t
  use iem_config, only: config_t
  use iem_rcb, only: rcb_t
  use iem_alloc_guard, only: alloc_guard_t
  use iem_strings, only: itoa, rtoa
  implicit none
  private
  public :: body_strip_t, number_body, classify_strip, strip_points, left_counts, &
            agree_first, node_weight

  !> This rank's strip: its cell rows a..b, its node rows na..nb (b, and ny on the last
  !> strip), and the materials of the cells of rows a-1..b+1, columns -1..nx.
  type :: body_strip_t
    integer :: a = 0, b = -1, na = 0, nb = -1
    integer(int8), allocatable :: mat(:, :)
  end type body_strip_t

  abstract interface
    !> Weight (>= 1) of the node at (x, y) in a weighted bisection.
    pure integer(i8) function node_weight(x, y)
      import :: wp, i8
      implicit none
      real(wp), intent(in) :: x, y
    end function node_weight
  end interface

contains

  !> Classify this rank's strip of the body (materials of its rows and one row around).
  !> hits(k): cells of the strip's rows whose centre shape k holds; cells(m): cells of
  !> material m in them. Collective: stat /= 0 with msg (the first failing rank's) on every
  !> rank for an unreadable, mis-sized or unmatched image, or no memory.
  subroutine classify_strip(body, comm, strip, hits, cells, stat, msg)
    type(body_t), intent(in) :: body
    type(MPI_Comm), intent(in) :: comm
    type(body_strip_t), intent(out) :: strip
    integer(i8), allocatable, intent(out) :: hits(:), cells(:)
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer(int8), allocatable :: src(:, :)
    integer :: rank, nranks, nx, ny, ierr

    call MPI_Comm_rank(comm, rank)
    call MPI_Comm_size(comm, nranks)
    nx = body%grid%nx
    ny = body%grid%ny
    strip%a = int(int(rank, i8)*ny/nranks)
    strip%b = int(int(rank + 1, i8)*ny/nranks) - 1
    strip%na = strip%a
    strip%nb = strip%b
    if (rank == nranks - 1) strip%nb = ny
    allocate(hits(size(body%shapes)), cells(body%n_materials))
    allocate(strip%mat(-1:nx, strip%a - 1:strip%b + 1), &
             src(-1:nx, strip%a - 1:strip%b + 1), stat=ierr)
    stat = 0
    msg = ''
    if (ierr /= 0) then
      stat = 1
      msg = body%grid%label()//': out of memory classifying the cells of a strip of '// &
            itoa(strip%b - strip%a + 3)//' rows'
    else
      call body%classify_rows(-1, nx, strip%a - 1, strip%b + 1, strip%a, strip%b, &
                              strip%mat, src, hits, cells, stat, msg)
    end if
    call agree_first(comm, stat, msg)
  end subroutine classify_strip

  !> Number the body of cfg: classify the strips, share the cells and nodes of every row
  !> (body%cell_first, node_first, n_cells, n_nodes, material_cells), and refuse what needs
  !> the whole body to see: a shape that holds no cell centre, an empty body, a material no
  !> cell uses. Collective: the same stat and msg on every rank. strip is kept for
  !> strip_points and left_counts.
  subroutine number_body(body, cfg, comm, strip, stat, msg)
    type(body_t), intent(inout) :: body
    type(config_t), intent(in) :: cfg
    type(MPI_Comm), intent(in) :: comm
    type(body_strip_t), intent(out) :: strip
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer(i8), allocatable :: hits(:), cells(:), rc(:), rn(:)
    integer, allocatable :: cnt(:), displ(:)
    integer :: rank, nranks, nx, ny, i, j, k, r

    call classify_strip(body, comm, strip, hits, cells, stat, msg)
    if (stat /= 0) return
    call MPI_Comm_rank(comm, rank)
    call MPI_Comm_size(comm, nranks)
    nx = body%grid%nx
    ny = body%grid%ny
    call MPI_Allreduce(MPI_IN_PLACE, hits, size(hits), MPI_INTEGER8, MPI_SUM, comm)
    call MPI_Allreduce(MPI_IN_PLACE, cells, size(cells), MPI_INTEGER8, MPI_SUM, comm)
    ! cells of every cell row and nodes of every node row, gathered in row order
    allocate(rc(0:ny - 1), rn(0:ny), cnt(0:nranks - 1), displ(0:nranks - 1))
    do j = strip%a, strip%b
      rc(j) = count(strip%mat(0:nx - 1, j) > 0)
    end do
    do j = strip%na, strip%nb
      rn(j) = 0
      do i = 0, nx
        if (any(strip%mat(i - 1:i, j - 1:j) > 0)) rn(j) = rn(j) + 1
      end do
    end do
    do r = 0, nranks - 1
      displ(r) = int(int(r, i8)*ny/nranks)
      cnt(r) = int(int(r + 1, i8)*ny/nranks) - displ(r)
    end do
    call MPI_Allgatherv(MPI_IN_PLACE, 0, MPI_INTEGER8, rc, cnt, displ, MPI_INTEGER8, comm)
    cnt(nranks - 1) = cnt(nranks - 1) + 1
    call MPI_Allgatherv(MPI_IN_PLACE, 0, MPI_INTEGER8, rn, cnt, displ, MPI_INTEGER8, comm)
    allocate(body%cell_first(0:ny), body%node_first(0:ny + 1))
    body%cell_first(0) = 0
    do j = 0, ny - 1
      body%cell_first(j + 1) = body%cell_first(j) + rc(j)
    end do
    body%node_first(0) = 0
    do j = 0, ny
      body%node_first(j + 1) = body%node_first(j) + rn(j)
    end do
    body%n_cells = body%cell_first(ny)
    body%n_nodes = body%node_first(ny + 1)
    body%material_cells = cells
    associate(grid => body%grid)
      do k = 1, size(hits)
        if (hits(k) == 0) then
          stat = 1
          msg = '&shape #'//itoa(k)//" ('"//trim(cfg%shapes(k)%name)//"'): holds no cell "// &
                'centre of the grid [0, '//rtoa(grid%nx*grid%lx)//'] x [0, '// &
                rtoa(grid%ny*grid%ly)//'] (outside it, or smaller than a cell of '// &
                rtoa(grid%lx)//' x '//rtoa(grid%ly)//' m)'
          return
        end if
      end do
      if (body%n_cells == 0) then
        stat = 1
        msg = '&geometry: the body is empty: no cell of the '//itoa(grid%nx)//' x '// &
              itoa(grid%ny)//' grid has a material (background, image and &shape groups)'
        return
      end if
    end associate
    do k = 1, body%n_materials
      if (cells(k) == 0) then
        stat = 1
        msg = '&material #'//itoa(k)//" ('"//trim(cfg%materials(k)%name)//"'): no cell of "// &
              'the body is of this material; remove it or give it to a &shape'
        return
      end if
    end do
  end subroutine number_body

  !> The nodes of this rank's node rows, their grid indices ij(2, n) and weights w(n) (1, or
  !> weight(x, y)), for the weighted bisection.
  subroutine strip_points(body, strip, ij, w, weight)
    type(body_t), intent(in) :: body
    type(body_strip_t), intent(in) :: strip
    integer, allocatable, intent(out) :: ij(:, :)
    integer(i8), allocatable, intent(out) :: w(:)
    procedure(node_weight), optional :: weight
    integer :: i, j, n, k
    n = 0
    do j = strip%na, strip%nb
      do i = 0, body%grid%nx
        if (used(i, j)) n = n + 1
      end do
    end do
    allocate(ij(2, n), w(n))
    k = 0
    do j = strip%na, strip%nb
      do i = 0, body%grid%nx
        if (.not. used(i, j)) cycle
        k = k + 1
        ij(:, k) = [i, j]
        w(k) = 1
        if (present(weight)) w(k) = weight(i*body%grid%lx, j*body%grid%ly)
      end do
    end do
  contains
    pure logical function used(i, j)
      integer, intent(in) :: i, j
      used = any(strip%mat(i - 1:i, j - 1:j) > 0)
    end function used
  end subroutine strip_points

  !> For this rank's bisection box (rcb%box) with c0 = max(i0 - 1, 0): lc(j), the cells of
  !> cell row j left of column c0, and ln(j), the nodes of node row j left of it, for the rows
  !> j of max(j0 - 1, 0) .. min(j1 + 1, ny) (lc(ny) = 0), from the ranks whose strips hold
  !> them. Collective.
  subroutine left_counts(body, strip, rcb, comm, lc, ln)
    type(body_t), intent(in) :: body
    type(body_strip_t), intent(in) :: strip
    type(rcb_t), intent(in) :: rcb
    type(MPI_Comm), intent(in) :: comm
    integer(i8), allocatable, intent(out) :: lc(:), ln(:)
    integer, allocatable :: scnt(:), sdis(:), rcnt(:), rdis(:)
    integer(i8), allocatable :: sbuf(:), rbuf(:)
    integer :: rank, nranks, p, j, i, k, r0, r1, c0, ny
    call MPI_Comm_rank(comm, rank)
    call MPI_Comm_size(comm, nranks)
    ny = body%grid%ny
    allocate(scnt(0:nranks - 1), sdis(0:nranks - 1), rcnt(0:nranks - 1), rdis(0:nranks - 1))
    ! what each rank's window needs of this strip's rows: (lc, ln) per row
    do p = 0, nranks - 1
      call window_rows(p, r0, r1)
      scnt(p) = 2*max(0, min(strip%nb, r1) - max(strip%na, r0) + 1)
    end do
    sdis = offsets(scnt)
    allocate(sbuf(sum(scnt)))
    k = 0
    do p = 0, nranks - 1
      call window_rows(p, r0, r1)
      c0 = max(rcb%box(1, p) - 1, 0)
      do j = max(strip%na, r0), min(strip%nb, r1)
        sbuf(k + 1) = 0
        if (j < ny) sbuf(k + 1) = count(strip%mat(0:c0 - 1, j) > 0)
        sbuf(k + 2) = 0
        do i = 0, c0 - 1
          if (any(strip%mat(i - 1:i, j - 1:j) > 0)) sbuf(k + 2) = sbuf(k + 2) + 1
        end do
        k = k + 2
      end do
    end do
    ! this rank's window rows, from the strips that hold them (in row order)
    call window_rows(rank, r0, r1)
    do p = 0, nranks - 1
      rcnt(p) = 2*max(0, min(last_node_row(p), r1) - max(first_row(p), r0) + 1)
    end do
    rdis = offsets(rcnt)
    allocate(rbuf(sum(rcnt)))
    call MPI_Alltoallv(sbuf, scnt, sdis, MPI_INTEGER8, rbuf, rcnt, rdis, MPI_INTEGER8, comm)
    allocate(lc(r0:r1), ln(r0:r1))
    do j = r0, r1
      lc(j) = rbuf(2*(j - r0) + 1)
      ln(j) = rbuf(2*(j - r0) + 2)
    end do

  contains

    !> Offsets of consecutive blocks of counts cnt(0:), the first at 0.
    pure function offsets(cnt) result(off)
      integer, intent(in) :: cnt(0:)
      integer :: off(0:size(cnt) - 1), q
      off(0) = 0
      do q = 1, size(cnt) - 1
        off(q) = off(q - 1) + cnt(q - 1)
      end do
    end function offsets

    subroutine window_rows(q, a, b)
      integer, intent(in) :: q
      integer, intent(out) :: a, b
      a = max(rcb%box(3, q) - 1, 0)
      b = min(rcb%box(4, q) + 1, ny)
    end subroutine window_rows

    integer function first_row(q)
      integer, intent(in) :: q
      first_row = int(int(q, i8)*ny/nranks)
    end function first_row

    integer function last_node_row(q)
      integer, intent(in) :: q
      last_node_row = int(int(q + 1, i8)*ny/nranks) - 1
      if (q == nranks - 1) last_node_row = ny
    end function last_node_row
  end subroutine left_counts

  !> Make every rank agree on a failure: stat and msg become those of the lowest failing rank
  !> (stat = 0 and msg = '' when none failed). Collective.
  subroutine agree_first(comm, stat, msg)
    type(MPI_Comm), intent(in) :: comm
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer :: rank, first, n
    call MPI_Comm_rank(comm, rank)
    first = huge(1)
    if (stat /= 0) first = rank
    call MPI_Allreduce(MPI_IN_PLACE, first, 1, MPI_INTEGER, MPI_MIN, comm)
    if (first == huge(1)) then
      stat = 0
      msg = ''
      return
    end if
    n = 0
    if (rank == first) n = len(msg)
    call MPI_Bcast(stat, 1, MPI_INTEGER, first, comm)
    call MPI_Bcast(n, 1, MPI_INTEGER, first, comm)
    if (rank /= first) then
      if (allocated(msg)) deallocate(msg)
      allocate(character(len=n) :: msg)
    end if
    if (n > 0) call MPI_Bcast(msg, n, MPI_CHARACTER, first, comm)
  end subroutine agree_first
end module iem_body_numbering
