!> Domain decomposition: each rank's share of the body by coordinate bisection, computed by
!> every rank alone for a full rectangle, and weighted by the nodes that exist (iem_rcb,
!> rcb_init_weighted over the strips of iem_body_numbering) for any other body or for given
!> node weights; then each rank's local lattice (owned + halo nodes, the cells touching owned
!> nodes) built from the window around its box alone, and its halo plan. No rank holds an
!> array over the body.
module iem_decomposition
  use mpi_f08, only: MPI_Comm, MPI_Comm_rank, MPI_Comm_size, MPI_Allreduce, MPI_IN_PLACE, &
                     MPI_SUM, MPI_INTEGER8
  use iem_kinds, only: wp, ip, i8
  use, intrinsic :: iso_fortran_env, only: int8
  use iem_body, only: body_t
  use iem_body_numbering, only: body_strip_t, classify_strip, strip_points, left_counts, &
                                agree_first, node_weight
  use iem_local_lattice, only: local_lattice_t
  use iem_cell_table, only: cell_table
  use iem_halo, only: halo_t
  use iem_rcb, only: rcb_t
  use iem_alloc_guard, only: alloc_guard_t
  use iem_sort, only: sort_i8
  use iem_strings, only: itoa
  implicit none
  private
  public :: decompose

contains

  !> Partition the body over the ranks of comm and build this rank's lattice and halo plan.
  !> The halo carries width values a node (default 4: u and v). A full rectangle without
  !> weights is bisected by node counts alone; any other body, or given node weights
  !> (weight(x, y) >= 1), by the weighted bisection of its existing nodes, from the strips of
  !> a numbered body (strip, from number_body; classified again when absent). With share(0:P-1)
  !> > 0 the ranks' parts are in proportion to it (load balancing). rcb returns the
  !> bisection (the owner of any node). Collective; stat /= 0 with msg on every rank when it
  !> fails (a failed allocation included).
  subroutine decompose(body, comm, lat, halo, stat, msg, width, weight, strip, rcb, share)
    type(body_t), intent(in) :: body
    type(MPI_Comm), intent(in) :: comm
    type(local_lattice_t), intent(inout) :: lat
    type(halo_t), intent(inout) :: halo
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer, intent(in), optional :: width
    procedure(node_weight), optional :: weight
    type(body_strip_t), intent(inout), optional :: strip
    type(rcb_t), intent(out), optional :: rcb
    real(wp), intent(in), optional :: share(0:)
    integer(ip), allocatable :: own(:)
    integer(i8), allocatable :: hits(:), cells(:), wts(:), lc(:), ln(:), nodes(:)
    integer, allocatable :: ij(:, :)
    type(body_strip_t) :: st
    type(rcb_t) :: bis
    integer :: nranks, rank, w, k
    type(alloc_guard_t) :: guard

    call MPI_Comm_size(comm, nranks)
    call MPI_Comm_rank(comm, rank)
    w = 4
    if (present(width)) w = width
    stat = 0
    msg = ''
    if (body%uniform .and. .not. present(weight)) then
      call bis%init(body%grid%nx + 1, body%grid%ny + 1, nranks, share)
      if (bis%balanced(2)) then
        ! every row is full: left of column c0 lie c0 cells and c0 nodes
        allocate(lc(0:bis%box(4, rank) - bis%box(3, rank) + 2), &
                 ln(0:bis%box(4, rank) - bis%box(3, rank) + 2))
        lc = max(bis%box(1, rank) - 1, 0)
        ln = lc
        call build_local_window(body, bis, rank, lc, ln, lat, own, guard, stat, msg)
        call guard%agree(comm, body%grid%label(), stat, msg)
        if (stat /= 0) return
        call build_halo(own, comm, lat, halo, w)
        if (present(rcb)) rcb = bis
        return
      end if
    end if
    ! the weighted bisection of the nodes of the strips
    if (present(strip)) then
      call move_alloc(strip%mat, st%mat)
      st%a = strip%a
      st%b = strip%b
      st%na = strip%na
      st%nb = strip%nb
    else
      call classify_strip(body, comm, st, hits, cells, stat, msg)
      if (stat /= 0) return
    end if
    call strip_points(body, st, ij, wts, weight)
    call bis%init_weighted(body%grid%nx + 1, body%grid%ny + 1, nranks, ij, wts, comm, share)
    allocate(nodes(0:nranks - 1))
    nodes = 0
    do k = 1, size(wts)
      nodes(bis%owner(ij(1, k), ij(2, k))) = nodes(bis%owner(ij(1, k), ij(2, k))) + 1
    end do
    deallocate(ij, wts)
    call MPI_Allreduce(MPI_IN_PLACE, nodes, nranks, MPI_INTEGER8, MPI_SUM, comm)
    if (any(nodes < 2)) then
      stat = 1
      msg = 'the body has fewer than 2 nodes on a rank ('//itoa(body%n_nodes)//' nodes, '// &
            itoa(nranks)//' ranks); use fewer ranks or a finer grid'
      return
    end if
    call left_counts(body, st, bis, comm, lc, ln)
    deallocate(st%mat)
    call build_local_window(body, bis, rank, lc, ln, lat, own, guard, stat, msg)
    call agree_first(comm, stat, msg)
    if (stat /= 0) return
    call guard%agree(comm, body%grid%label(), stat, msg)
    if (stat /= 0) return
    call build_halo(own, comm, lat, halo, w)
    if (present(rcb)) rcb = bis
  end subroutine decompose

  !> Build the local lattice of rank me from its bisection box alone: the window of cells
  !> around the box is classified here, and numbered from the rows' first numbers
  !> (body%cell_first, node_first) and the counts left of the window (lc, ln, see
  !> left_counts). Owned nodes are the box's (ascending), cells those touching them
  !> (ascending), halo nodes sorted by (owner, number); own(n_local) the owner of each local
  !> node. stat /= 0 with msg if the image cannot be read; a failed allocation goes to guard.
  subroutine build_local_window(body, rcb, me, lc, ln, lat, own, guard, stat, msg)
    type(body_t), intent(in) :: body
    type(rcb_t), intent(in) :: rcb
    integer, intent(in) :: me
    integer(i8), intent(in) :: lc(0:), ln(0:)
    type(local_lattice_t), intent(inout) :: lat
    integer(ip), allocatable, intent(out) :: own(:)
    type(alloc_guard_t), intent(inout) :: guard
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer(int8), allocatable :: mat(:, :), src(:, :)
    integer(i8), allocatable :: nid(:, :), keys(:), hits(:), cells(:)
    integer(ip), allocatable :: lmap(:, :), cn(:, :)
    integer(i8) :: g, c, nn, pg
    integer :: i0, i1, j0, j1, a0, a1, b0, b1, r0, i, j, q, k, l, n_owned, n_halo, n_cells
    integer :: ierr, nx, ny, n_runs, r, pi, pj
    logical :: shapes
    integer, parameter :: di(4) = [0, 1, 0, -1], dj(4) = [-1, 0, 1, 0]
    integer, parameter :: ci(4) = [0, 1, 1, 0], cj(4) = [0, 0, 1, 1]

    call lat%free()
    nx = body%grid%nx
    ny = body%grid%ny
    nn = body%n_nodes
    i0 = rcb%box(1, me)
    i1 = rcb%box(2, me)
    j0 = rcb%box(3, me)
    j1 = rcb%box(4, me)
    ! nodes of the window: the box and the ring around it, within the grid; rows r0.. of lc
    a0 = max(i0 - 1, 0)
    a1 = min(i1 + 1, nx)
    b0 = max(j0 - 1, 0)
    b1 = min(j1 + 1, ny)
    r0 = b0
    allocate(mat(i0 - 2:i1 + 1, j0 - 2:j1 + 1), src(i0 - 2:i1 + 1, j0 - 2:j1 + 1), &
             nid(a0:a1, b0:b1), lmap(a0:a1, b0:b1), hits(size(body%shapes)), &
             cells(body%n_materials), stat=ierr)
    call guard%note(ierr, 'the window of the rank', 34.0_wp*(a1 - a0 + 3)*(b1 - b0 + 3))
    stat = 0
    msg = ''
    if (guard%failed) return
    call body%classify_rows(i0 - 2, i1 + 1, j0 - 2, j1 + 1, 1, 0, mat, src, hits, cells, &
                            stat, msg)
    if (stat /= 0) return
    ! numbers of the window's nodes: the row's first, those left of the window, then along
    do j = b0, b1
      g = body%node_first(j) + ln(j - r0)
      do i = a0, a1
        if (any(mat(i - 1:i, j - 1:j) > 0)) then
          nid(i, j) = g
          g = g + 1
        else
          nid(i, j) = -1
        end if
      end do
    end do
    ! owned nodes (the box's), local cells (touching them), halo nodes (their other corners)
    n_owned = count(nid(i0:i1, j0:j1) >= 0)
    n_cells = count(mat(a0:min(i1, nx - 1), b0:min(j1, ny - 1)) > 0)
    lmap = 0
    l = 0
    do j = j0, j1
      do i = i0, i1
        if (nid(i, j) < 0) cycle
        l = l + 1
        lmap(i, j) = int(l, ip)
      end do
    end do
    n_halo = 0
    do j = b0, min(j1, ny - 1)
      do i = a0, min(i1, nx - 1)
        if (mat(i, j) <= 0) cycle
        do q = 1, 4
          if (lmap(i + ci(q), j + cj(q)) == 0) then
            lmap(i + ci(q), j + cj(q)) = -1
            n_halo = n_halo + 1
          end if
        end do
      end do
    end do
    shapes = size(body%shapes) > 0
    ! the cells' materials only when there are several (lat%mat)
    lat%mixed = body%n_materials > 1
    ! the owned nodes' runs along the rows: a run ends where the next owned node is not the
    ! right neighbour, or not the next number
    n_runs = 0
    pi = -2
    pj = -1
    pg = -2
    do j = j0, j1
      do i = i0, i1
        if (nid(i, j) < 0) cycle
        if (j /= pj .or. i /= pi + 1 .or. nid(i, j) /= pg + 1) n_runs = n_runs + 1
        pi = i
        pj = j
        pg = nid(i, j)
      end do
    end do
    allocate(keys(n_halo), lat%run_i(n_runs), lat%run_j(n_runs), lat%halo_gid(n_halo), &
             lat%halo_ij(2, n_halo), own(n_owned + n_halo), cn(4, n_cells), &
             lat%cell_mat(merge(n_cells, 0, lat%mixed)), lat%cell_open(n_cells), stat=ierr)
    if (ierr == 0 .and. shapes) allocate(lat%cell_src(n_cells), lat%side_src(4, n_cells), &
                                         stat=ierr)
    call guard%note(ierr, 'the lattice of the rank', 4.0_wp*(n_owned + n_halo) + &
                    24.0_wp*n_halo + 20.0_wp*n_runs + merge(21.0_wp, 17.0_wp, lat%mixed)*n_cells)
    if (guard%failed) return
    call lat%node_runs%init(n_runs)
    call lat%cell_runs%init(max(0, min(j1, ny - 1) - b0 + 1))
    l = 0
    pi = -2
    pj = -1
    do j = j0, j1
      do i = i0, i1
        if (nid(i, j) < 0) cycle
        l = l + 1
        ! a run stays in its grid row
        call lat%node_runs%add(nid(i, j), j /= pj .or. i /= pi + 1, r)
        lat%run_i(r) = i - (l - lat%node_runs%first(r))
        lat%run_j(r) = j
        pi = i
        pj = j
        own(l) = int(me, ip)
      end do
    end do
    k = 0
    do j = b0, b1
      do i = a0, a1
        if (lmap(i, j) /= -1) cycle
        k = k + 1
        keys(k) = int(rcb%owner(i, j), i8)*nn + nid(i, j)
      end do
    end do
    call sort_i8(keys)
    do k = 1, n_halo
      l = n_owned + k
      lat%halo_gid(k) = mod(keys(k), nn)
      own(l) = int(keys(k)/nn, ip)
    end do
    ! place the ring's halo nodes: each one's slot by binary search of its (owner, number)
    do j = b0, b1
      do i = a0, a1
        if (lmap(i, j) /= -1) cycle
        k = find_key(keys, int(rcb%owner(i, j), i8)*nn + nid(i, j))
        lmap(i, j) = int(n_owned + k, ip)
        lat%halo_ij(:, k) = [i, j]
      end do
    end do
    lat%n_owned = n_owned
    lat%n_local = n_owned + n_halo
    lat%lx = body%grid%lx
    lat%ly = body%grid%ly
    lat%n_cells = n_cells
    ! the cells' numbers: runs of consecutive numbers (at most one a row of the window)
    k = 0
    do j = b0, min(j1, ny - 1)
      c = body%cell_first(j) + lc(j - r0)
      do i = a0, min(i1, nx - 1)
        if (mat(i, j) <= 0) cycle
        k = k + 1
        call lat%cell_runs%add(c, .false., r)
        c = c + 1
        cn(:, k) = [(lmap(i + ci(q), j + cj(q)), q = 1, 4)]
        if (lat%mixed) lat%cell_mat(k) = mat(i, j)
        lat%cell_open(k) = 0_int8
        do q = 1, 4
          if (mat(i + di(q), j + dj(q)) == 0) lat%cell_open(k) = ibset(lat%cell_open(k), q - 1)
        end do
        if (shapes) then
          lat%cell_src(k) = src(i, j)
          lat%side_src(:, k) = [(src(i + di(q), j + dj(q)), q = 1, 4)]
        end if
      end do
    end do
    ! the cells' corners as the force kernel's chunks (listed only where not consecutive)
    lat%cells = cell_table(cn)
  end subroutine build_local_window

  !> Position of key in the ascending list keys (which holds it).
  pure integer function find_key(keys, key) result(k)
    integer(i8), intent(in) :: keys(:), key
    integer :: lo, hi
    lo = 1
    hi = size(keys)
    do while (lo < hi)
      k = (lo + hi)/2
      if (keys(k) < key) then
        lo = k + 1
      else
        hi = k
      end if
    end do
    k = lo
  end function find_key

  !> Build the halo plan: whom we receive from (contiguous halo ranges) and what we send: an
  !> owned node goes to every rank that owns a node of one of its cells.
  subroutine build_halo(own, comm, lat, halo, width)
    !> The rank that owns each local node.
    integer(ip), intent(in) :: own(:)
    type(MPI_Comm), intent(in) :: comm
    type(local_lattice_t), intent(in) :: lat
    type(halo_t), intent(inout) :: halo
    integer, intent(in) :: width
    integer, allocatable :: ranks(:)
    integer(ip), allocatable :: recv_first(:), send_first(:), send_node(:), cnt(:), pos(:)
    integer, allocatable :: nb_of(:)
    logical, allocatable :: sends(:, :)
    integer :: nb, k, l, q, p, c, r, corner(4)

    ! neighbours = owners of halo nodes, in the order the halo is sorted (by owner)
    nb = 0
    allocate(ranks(0))
    do l = lat%n_owned + 1, lat%n_local
      r = own(l)
      if (nb == 0) then
        ranks = [ranks, r]
        nb = 1
      else if (ranks(nb) /= r) then
        ranks = [ranks, r]
        nb = nb + 1
      end if
    end do
    allocate(recv_first(nb + 1), nb_of(lat%n_local))
    nb_of = 0
    k = 0
    do l = lat%n_owned + 1, lat%n_local
      r = own(l)
      if (k == 0) then
        k = 1
        recv_first(1) = int(l, ip)
      else if (ranks(k) /= r) then
        k = k + 1
        recv_first(k) = int(l, ip)
      end if
      nb_of(l) = k
    end do
    recv_first(nb + 1) = int(lat%n_local + 1, ip)
    ! owned corner p of a cell goes to the owner of every halo corner q of that cell
    allocate(sends(lat%n_owned, nb))
    sends = .false.
    do c = 1, lat%n_cells
      corner = lat%corners(c)
      do q = 1, 4
        if (nb_of(corner(q)) == 0) cycle
        do p = 1, 4
          if (corner(p) <= lat%n_owned) sends(corner(p), nb_of(corner(q))) = .true.
        end do
      end do
    end do
    allocate(cnt(nb), send_first(nb + 1), pos(nb))
    do k = 1, nb
      cnt(k) = int(count(sends(:, k)), ip)
    end do
    allocate(send_node(sum(cnt)))
    send_first(1) = 1
    do k = 1, nb
      send_first(k + 1) = send_first(k) + cnt(k)
    end do
    pos = send_first(1:nb)
    do k = 1, nb
      do l = 1, lat%n_owned
        if (.not. sends(l, k)) cycle
        send_node(pos(k)) = int(l, ip)
        pos(k) = pos(k) + 1
      end do
    end do
    call halo%init(comm, ranks, recv_first, send_first, send_node, width)
  end subroutine build_halo
end module iem_decomposition
