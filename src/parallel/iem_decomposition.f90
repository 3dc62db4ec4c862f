!> Domain decomposition: METIS partition of the body's nodes (on rank 0, broadcast; partition),
!> then each rank's local lattice (owned + halo nodes, cells touching owned nodes, from the body's
!> cell-to-node table) and its halo plan (from the cells that join owned and halo nodes; build).
module iem_decomposition
  use mpi_f08, only: MPI_Comm, MPI_Comm_rank, MPI_Comm_size, MPI_Bcast, MPI_INTEGER
  use iem_kinds, only: wp, ip, i8, mpi_ip
  use iem_build_info, only: metis_idx
  use, intrinsic :: iso_fortran_env, only: int8
  use iem_body, only: body_t
  use iem_local_lattice, only: local_lattice_t
  use iem_halo, only: halo_t
  use iem_rcb, only: rcb_t
  use iem_metis, only: partition_body, partition_ok, partition_no_memory, &
                       partition_metis_no_memory
  use iem_alloc_guard, only: alloc_guard_t
  use iem_memory, only: bytes_text
  use iem_sort, only: sort_i8
  use iem_strings, only: itoa
  implicit none
  private
  public :: decompose, partition, build

contains

  !> Partition the body over the ranks of comm and build this rank's lattice and halo plan.
  !> The halo carries width values a node (default 4: u and v). Collective; stat /= 0 with msg
  !> on every rank when it fails (a failed allocation included).
  subroutine decompose(body, comm, lat, halo, stat, msg, width)
    type(body_t), intent(in) :: body
    type(MPI_Comm), intent(in) :: comm
    type(local_lattice_t), intent(inout) :: lat
    type(halo_t), intent(inout) :: halo
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer, intent(in), optional :: width
    integer(ip), allocatable :: part(:)
    type(rcb_t) :: rcb
    integer :: nranks, rank, w
    type(alloc_guard_t) :: guard

    call MPI_Comm_size(comm, nranks)
    call MPI_Comm_rank(comm, rank)
    ! a full rectangle on several ranks: coordinate bisection, which every rank computes
    ! alone, so no rank holds an array over the whole body
    if (body%uniform .and. nranks > 1) then
      call rcb%init(body%grid%nx + 1, body%grid%ny + 1, nranks)
      if (rcb%balanced(2)) then
        stat = 0
        msg = ''
        call build_local_rcb(body, rcb, rank, lat, part, guard)
        call guard%agree(comm, body%grid%label(), stat, msg)
        if (stat /= 0) return
        w = 4
        if (present(width)) w = width
        call build_halo(part, comm, lat, halo, w)
        return
      end if
    end if
    call partition(body, comm, part, stat, msg)
    if (stat /= 0) return
    call build(body, part, comm, lat, halo, stat, msg, width)
  end subroutine decompose

  !> Build the local lattice of rank me of a full rectangle from its bisection box: owned
  !> nodes the box's (ascending), the cells touching them (ascending), halo nodes the ring
  !> around the box sorted by (owner, number); own(n_local) the owner of each local node.
  !> Only arrays of the rank's size are allocated.
  subroutine build_local_rcb(body, rcb, me, lat, own, guard)
    type(body_t), intent(in) :: body
    type(rcb_t), intent(in) :: rcb
    integer, intent(in) :: me
    type(local_lattice_t), intent(inout) :: lat
    integer(ip), allocatable, intent(out) :: own(:)
    type(alloc_guard_t), intent(inout) :: guard
    integer(ip), allocatable :: lmap(:, :)
    integer(i8), allocatable :: keys(:)
    integer :: i0, i1, j0, j1, a0, a1, b0, b1, i, j, n_owned, n_halo, n_cells, k, l, q, ierr
    integer :: ij(2)
    integer(i8) :: nn
    integer, parameter :: di(4) = [0, 1, 0, -1], dj(4) = [-1, 0, 1, 0]
    integer, parameter :: ci(4) = [0, 1, 1, 0], cj(4) = [0, 0, 1, 1]

    call lat%free()
    nn = body%n_nodes
    i0 = rcb%box(1, me)
    i1 = rcb%box(2, me)
    j0 = rcb%box(3, me)
    j1 = rcb%box(4, me)
    ! the box grown by the ring of halo nodes, within the grid; its cells
    a0 = max(i0 - 1, 0)
    a1 = min(i1 + 1, body%grid%nx)
    b0 = max(j0 - 1, 0)
    b1 = min(j1 + 1, body%grid%ny)
    n_owned = (i1 - i0 + 1)*(j1 - j0 + 1)
    n_halo = (a1 - a0 + 1)*(b1 - b0 + 1) - n_owned
    n_cells = (min(i1, body%grid%nx - 1) - a0 + 1)*(min(j1, body%grid%ny - 1) - b0 + 1)
    allocate(lmap(a0:a1, b0:b1), keys(n_halo), lat%gid(n_owned + n_halo), &
             lat%xy(2, n_owned + n_halo), own(n_owned + n_halo), lat%cell_gid(n_cells), &
             lat%cell_nodes(4, n_cells), lat%cell_mat(n_cells), lat%cell_open(n_cells), &
             stat=ierr)
    call guard%note(ierr, 'the lattice of the rank', 44.0_wp*(n_owned + n_halo) + &
                    29.0_wp*n_cells)
    if (guard%failed) return
    l = 0
    do j = j0, j1
      do i = i0, i1
        l = l + 1
        lmap(i, j) = int(l, ip)
        lat%gid(l) = body%node_number(i, j)
        own(l) = int(me, ip)
      end do
    end do
    k = 0
    do j = b0, b1
      do i = a0, a1
        if (i >= i0 .and. i <= i1 .and. j >= j0 .and. j <= j1) cycle
        k = k + 1
        keys(k) = int(rcb%owner(i, j), i8)*nn + body%node_number(i, j)
      end do
    end do
    call sort_i8(keys)
    do k = 1, n_halo
      l = n_owned + k
      lat%gid(l) = mod(keys(k), nn)
      own(l) = int(keys(k)/nn, ip)
      ij = body%node_ij(lat%gid(l))
      lmap(ij(1), ij(2)) = int(l, ip)
    end do
    lat%n_owned = n_owned
    lat%n_local = n_owned + n_halo
    lat%n_cells = n_cells
    lat%mixed = .false.
    do l = 1, lat%n_local
      lat%xy(:, l) = body%node_xy(lat%gid(l))
    end do
    k = 0
    do j = b0, min(j1, body%grid%ny - 1)
      do i = a0, min(i1, body%grid%nx - 1)
        k = k + 1
        lat%cell_gid(k) = body%cell_number(i, j)
        lat%cell_nodes(:, k) = [(lmap(i + ci(q), j + cj(q)), q = 1, 4)]
        lat%cell_mat(k) = body%material(i, j)
        lat%cell_open(k) = 0_int8
        do q = 1, 4
          if (body%material(i + di(q), j + dj(q)) == 0) &
            lat%cell_open(k) = ibset(lat%cell_open(k), q - 1)
        end do
      end do
    end do
  end subroutine build_local_rcb

  !> Part (rank, 0-based) of every node of the body, part(0:n_nodes-1) on every rank: METIS on
  !> rank 0 over the whole body, broadcast. vwgt(0:n_nodes-1) (read on rank 0 only) weighs
  !> the nodes (each >= 1, their sum within METIS's integer; default all 1); nparts (default
  !> the size of comm) is the number of parts. Collective; stat /= 0 with msg on every rank
  !> when it fails.
  subroutine partition(body, comm, part, stat, msg, vwgt, nparts)
    type(body_t), intent(in) :: body
    type(MPI_Comm), intent(in) :: comm
    integer(ip), allocatable, intent(out) :: part(:)
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer(ip), intent(in), optional :: vwgt(0:)
    integer, intent(in), optional :: nparts
    integer :: ierr, rank, nranks
    integer(i8) :: n
    type(alloc_guard_t) :: guard

    call MPI_Comm_rank(comm, rank)
    call MPI_Comm_size(comm, nranks)
    if (present(nparts)) nranks = nparts
    stat = 0
    msg = ''
    if (body%n_nodes < 2*nranks) then
      stat = 1
      msg = 'the body has fewer than 2 nodes per rank; use fewer ranks or a finer grid'
      return
    end if
    n = body%n_nodes
    if (present(vwgt) .and. rank == 0) then
      if (size(vwgt, kind=i8) /= n) then
        stat = 1
      else if (any(vwgt < 1)) then
        stat = 1
      else if (sum(int(vwgt, i8)) > huge(1_metis_idx)) then
        stat = 1
      end if
    end if
    call MPI_Bcast(stat, 1, MPI_INTEGER, 0, comm)
    if (stat /= 0) then
      msg = 'partition: the vertex weights must be one per node of the body, each >= 1, '// &
            'their sum within METIS''s integer'
      return
    end if
    allocate(part(0:n - 1), stat=ierr)
    call guard%note(ierr, 'the partition of the whole body', 4.0_wp*n)
    call guard%agree(comm, body%grid%label(), stat, msg)
    if (stat /= 0) return
    if (rank == 0) call partition_body(body, nranks, part, stat, vwgt)
    call MPI_Bcast(stat, 1, MPI_INTEGER, 0, comm)
    select case (stat)
    case (partition_ok)
    case (partition_no_memory)
      msg = body%grid%label()//': out of memory on rank 0: allocating the METIS graph of '// &
            'the whole body (about '//bytes_text(10.0_wp*n*storage_size(1_metis_idx)/8)// &
            ') failed; use a coarser grid or a node with more memory for rank 0 '// &
            '(docs/input.md, Limits)'
    case (partition_metis_no_memory)
      msg = body%grid%label()//': METIS_PartGraphKway ran out of memory on rank 0; use a '// &
            'coarser grid or a node with more memory for rank 0 (docs/input.md, Limits)'
    case default
      msg = 'METIS_PartGraphKway failed'
    end select
    if (stat /= partition_ok) return
    call MPI_Bcast(part, int(n), mpi_ip(), 0, comm)
  end subroutine partition

  !> Build this rank's lattice and halo plan (width values a node, default 4) from the part
  !> array part(0:n_nodes-1), the same on every rank, with values 0 .. size of comm - 1.
  !> Collective; stat /= 0 with msg on every rank when it fails.
  subroutine build(body, part, comm, lat, halo, stat, msg, width)
    type(body_t), intent(in) :: body
    integer(ip), intent(in) :: part(0:)
    type(MPI_Comm), intent(in) :: comm
    type(local_lattice_t), intent(inout) :: lat
    type(halo_t), intent(inout) :: halo
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer, intent(in), optional :: width
    integer :: w, rank, nranks
    type(alloc_guard_t) :: guard

    call MPI_Comm_rank(comm, rank)
    call MPI_Comm_size(comm, nranks)
    stat = 0
    msg = ''
    if (size(part, kind=i8) /= body%n_nodes .or. any(part < 0 .or. part >= nranks)) then
      stat = 1
      msg = 'build: the part array must hold one rank (0 .. '//itoa(nranks - 1)// &
            ') per node of the body'
      return
    end if
    call build_local(body, part, rank, lat, guard)
    call guard%agree(comm, body%grid%label(), stat, msg)
    if (stat /= 0) return
    w = 4
    if (present(width)) w = width
    call build_halo(part(lat%gid(1:lat%n_local)), comm, lat, halo, w)
  end subroutine build

  !> Build the local lattice of rank `me` from the global part array; a failed allocation is
  !> noted in guard (and the lattice left incomplete).
  subroutine build_local(body, part, me, lat, guard)
    type(body_t), intent(in) :: body
    integer(ip), intent(in) :: part(0:)
    integer, intent(in) :: me
    type(local_lattice_t), intent(inout) :: lat
    type(alloc_guard_t), intent(inout) :: guard
    integer(ip), allocatable :: g2l(:)
    integer(i8), allocatable :: keys(:)
    integer(i8) :: g, c, corners(4), nn
    integer :: n_owned, n_cells, n_halo, k, q, l, ierr, ij(2)
    integer, parameter :: di(4) = [0, 1, 0, -1], dj(4) = [-1, 0, 1, 0]

    call lat%free()
    nn = body%n_nodes
    allocate(g2l(0:nn - 1), stat=ierr)
    call guard%note(ierr, 'the global-to-local node map', 4.0_wp*nn)
    if (guard%failed) return
    g2l = 0
    n_owned = count(part == me)
    ! cells touching an owned node, ascending
    n_cells = 0
    do c = 0, body%n_cells - 1
      corners = body%cell_corners(c)
      if (any(part(corners) == me)) n_cells = n_cells + 1
    end do
    allocate(lat%cell_gid(n_cells), lat%cell_nodes(4, n_cells), lat%cell_mat(n_cells), &
             lat%cell_open(n_cells), stat=ierr)
    call guard%note(ierr, 'the cells of the rank', 29.0_wp*n_cells)
    if (guard%failed) return
    k = 0
    do c = 0, body%n_cells - 1
      corners = body%cell_corners(c)
      if (any(part(corners) == me)) then
        k = k + 1
        lat%cell_gid(k) = c
      end if
    end do
    ! owned nodes ascending, then halo nodes sorted by (owner, global number)
    l = 0
    do g = 0, nn - 1
      if (part(g) == me) then
        l = l + 1
        g2l(g) = int(l, ip)
      end if
    end do
    n_halo = 0
    do k = 1, n_cells
      corners = body%cell_corners(lat%cell_gid(k))
      do q = 1, 4
        if (g2l(corners(q)) == 0) then
          g2l(corners(q)) = -1
          n_halo = n_halo + 1
        end if
      end do
    end do
    allocate(keys(n_halo), lat%gid(n_owned + n_halo), lat%xy(2, n_owned + n_halo), stat=ierr)
    call guard%note(ierr, 'the nodes of the rank', 24.0_wp*n_owned + 32.0_wp*n_halo)
    if (guard%failed) return
    n_halo = 0
    do k = 1, n_cells
      corners = body%cell_corners(lat%cell_gid(k))
      do q = 1, 4
        g = corners(q)
        if (g2l(g) == -1) then
          g2l(g) = -2
          n_halo = n_halo + 1
          keys(n_halo) = int(part(g), i8)*nn + g
        end if
      end do
    end do
    call sort_i8(keys)
    lat%n_owned = n_owned
    lat%n_local = n_owned + n_halo
    lat%n_cells = n_cells
    l = 0
    do g = 0, nn - 1
      if (part(g) == me) then
        l = l + 1
        lat%gid(l) = g
      end if
    end do
    do k = 1, n_halo
      g = mod(keys(k), nn)
      lat%gid(n_owned + k) = g
      g2l(g) = int(n_owned + k, ip)
    end do
    do l = 1, lat%n_local
      lat%xy(:, l) = body%node_xy(lat%gid(l))
    end do
    lat%mixed = body%n_materials > 1
    do k = 1, n_cells
      lat%cell_nodes(:, k) = g2l(body%cell_corners(lat%cell_gid(k)))
      ij = body%cell_ij(lat%cell_gid(k))
      lat%cell_mat(k) = body%material(ij(1), ij(2))
      lat%cell_open(k) = 0_int8
      do q = 1, 4
        if (body%material(ij(1) + di(q), ij(2) + dj(q)) == 0) &
          lat%cell_open(k) = ibset(lat%cell_open(k), q - 1)
      end do
    end do
  end subroutine build_local

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
    integer :: nb, k, l, q, p, c, r

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
      do q = 1, 4
        if (nb_of(lat%cell_nodes(q, c)) == 0) cycle
        do p = 1, 4
          if (lat%cell_nodes(p, c) <= lat%n_owned) sends(lat%cell_nodes(p, c), &
                                                         nb_of(lat%cell_nodes(q, c))) = .true.
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
