!> Domain decomposition: METIS partition of the grid's nodes (on rank 0, broadcast), then each
!> rank's local lattice (owned + halo nodes, cells touching owned nodes) and its halo plan.
module iem_decomposition
  use mpi_f08, only: MPI_Comm, MPI_Comm_rank, MPI_Comm_size, MPI_Bcast, MPI_INTEGER
  use iem_kinds, only: wp, ip, i8, mpi_ip
  use iem_build_info, only: metis_idx
  use iem_grid, only: grid_t
  use iem_local_lattice, only: local_lattice_t
  use iem_halo, only: halo_t
  use iem_metis, only: partition_grid, partition_ok, partition_no_memory, &
                       partition_metis_no_memory
  use iem_limits, only: metis_graph_entries
  use iem_alloc_guard, only: alloc_guard_t
  use iem_memory, only: bytes_text
  use iem_sort, only: sort_i8
  implicit none
  private
  public :: decompose

contains

  !> Partition the grid over the ranks of comm and build this rank's lattice and halo plan.
  !> The halo carries width values a node (default 4: u and v). Collective; stat /= 0 with msg
  !> on every rank when it fails (a failed allocation included).
  subroutine decompose(grid, comm, lat, halo, stat, msg, width)
    type(grid_t), intent(in) :: grid
    type(MPI_Comm), intent(in) :: comm
    type(local_lattice_t), intent(inout) :: lat
    type(halo_t), intent(inout) :: halo
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer, intent(in), optional :: width
    integer :: w, ierr
    integer(ip), allocatable :: part(:)
    integer :: rank, nranks
    integer(i8) :: n
    type(alloc_guard_t) :: guard

    call MPI_Comm_rank(comm, rank)
    call MPI_Comm_size(comm, nranks)
    stat = 0
    msg = ''
    if (grid%n_nodes < 2*nranks) then
      stat = 1
      msg = 'the grid has fewer than 2 nodes per rank; use fewer ranks or a finer grid'
      return
    end if
    n = grid%n_nodes
    allocate(part(0:n - 1), stat=ierr)
    call guard%note(ierr, 'the partition of the whole body', 4.0_wp*n)
    call guard%agree(comm, grid%label(), stat, msg)
    if (stat /= 0) return
    if (rank == 0) call partition_grid(grid, nranks, part, stat)
    call MPI_Bcast(stat, 1, MPI_INTEGER, 0, comm)
    select case (stat)
    case (partition_ok)
    case (partition_no_memory)
      msg = grid%label()//': out of memory on rank 0: allocating the METIS graph of the '// &
            'whole body ('//bytes_text(real(metis_graph_entries(grid) + 2*n, wp)* &
            storage_size(1_metis_idx)/8)//') failed; use a coarser grid or a node with '// &
            'more memory for rank 0 (docs/input.md, Limits)'
    case (partition_metis_no_memory)
      msg = grid%label()//': METIS_PartGraphKway ran out of memory on rank 0; use a '// &
            'coarser grid or a node with more memory for rank 0 (docs/input.md, Limits)'
    case default
      msg = 'METIS_PartGraphKway failed'
    end select
    if (stat /= partition_ok) return
    call MPI_Bcast(part, int(n), mpi_ip(), 0, comm)
    call build_local(grid, part, rank, lat, guard)
    call guard%agree(comm, grid%label(), stat, msg)
    if (stat /= 0) return
    w = 4
    if (present(width)) w = width
    call build_halo(grid, part, rank, comm, lat, halo, w)
  end subroutine decompose

  !> Build the local lattice of rank `me` from the global part array; a failed allocation is
  !> noted in guard (and the lattice left incomplete).
  subroutine build_local(grid, part, me, lat, guard)
    type(grid_t), intent(in) :: grid
    integer(ip), intent(in) :: part(0:)
    integer, intent(in) :: me
    type(local_lattice_t), intent(inout) :: lat
    type(alloc_guard_t), intent(inout) :: guard
    integer(ip), allocatable :: g2l(:)
    integer(i8), allocatable :: keys(:), cell_gid(:)
    integer(i8) :: g, c, corners(4), nn
    integer :: n_owned, n_cells, n_halo, k, q, l, ierr

    call lat%free()
    lat%nx = grid%nx
    lat%ny = grid%ny
    nn = grid%n_nodes
    allocate(g2l(0:nn - 1), stat=ierr)
    call guard%note(ierr, 'the global-to-local node map', 4.0_wp*nn)
    if (guard%failed) return
    g2l = 0
    n_owned = count(part == me)
    ! cells touching an owned node, ascending
    n_cells = 0
    do c = 0, grid%n_cells - 1
      corners = grid%cell_corners(c)
      if (any(part(corners) == me)) n_cells = n_cells + 1
    end do
    allocate(cell_gid(n_cells), lat%cell_nodes(4, n_cells), stat=ierr)
    call guard%note(ierr, 'the cells of the rank', 24.0_wp*n_cells)
    if (guard%failed) return
    k = 0
    do c = 0, grid%n_cells - 1
      corners = grid%cell_corners(c)
      if (any(part(corners) == me)) then
        k = k + 1
        cell_gid(k) = c
      end if
    end do
    ! owned nodes ascending, then halo nodes sorted by (owner, global index)
    l = 0
    do g = 0, nn - 1
      if (part(g) == me) then
        l = l + 1
        g2l(g) = int(l, ip)
      end if
    end do
    n_halo = 0
    do k = 1, n_cells
      corners = grid%cell_corners(cell_gid(k))
      do q = 1, 4
        if (g2l(corners(q)) == 0) then
          g2l(corners(q)) = -1
          n_halo = n_halo + 1
        end if
      end do
    end do
    allocate(keys(n_halo), lat%gid(n_owned + n_halo), stat=ierr)
    call guard%note(ierr, 'the nodes of the rank', 8.0_wp*n_owned + 16.0_wp*n_halo)
    if (guard%failed) return
    n_halo = 0
    do k = 1, n_cells
      corners = grid%cell_corners(cell_gid(k))
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
    do k = 1, n_cells
      lat%cell_nodes(:, k) = g2l(grid%cell_corners(cell_gid(k)))
    end do
  end subroutine build_local

  !> Build the halo plan: whom we receive from (contiguous halo ranges) and what we send.
  subroutine build_halo(grid, part, me, comm, lat, halo, width)
    type(grid_t), intent(in) :: grid
    integer(ip), intent(in) :: part(0:)
    integer, intent(in) :: me
    type(MPI_Comm), intent(in) :: comm
    type(local_lattice_t), intent(in) :: lat
    type(halo_t), intent(inout) :: halo
    integer, intent(in) :: width
    integer, allocatable :: ranks(:)
    integer(ip), allocatable :: recv_first(:), send_first(:), send_node(:), cnt(:), pos(:)
    integer :: nb, k, l, q, r, di, dj, ii, jj, nranks_seen
    integer :: need(9)
    logical :: dup

    ! neighbours = owners of halo nodes, in the order the halo is sorted (by owner)
    nb = 0
    allocate(ranks(0))
    do l = lat%n_owned + 1, lat%n_local
      r = part(lat%gid(l))
      if (nb == 0) then
        ranks = [ranks, r]
        nb = 1
      else if (ranks(nb) /= r) then
        ranks = [ranks, r]
        nb = nb + 1
      end if
    end do
    allocate(recv_first(nb + 1))
    k = 0
    do l = lat%n_owned + 1, lat%n_local
      r = part(lat%gid(l))
      if (k == 0) then
        k = 1
        recv_first(1) = int(l, ip)
      else if (ranks(k) /= r) then
        k = k + 1
        recv_first(k) = int(l, ip)
      end if
    end do
    recv_first(nb + 1) = int(lat%n_local + 1, ip)
    ! send lists: owned node l goes to every other rank owning a node of one of its cells
    allocate(cnt(nb), source=0_ip)
    do l = 1, lat%n_owned
      call ranks_needing(l, need, nranks_seen)
      do k = 1, nranks_seen
        r = findloc(ranks, need(k), 1)
        cnt(r) = cnt(r) + 1
      end do
    end do
    allocate(send_first(nb + 1), send_node(sum(cnt)), pos(nb))
    send_first(1) = 1
    do k = 1, nb
      send_first(k + 1) = send_first(k) + cnt(k)
    end do
    pos = send_first(1:nb)
    do l = 1, lat%n_owned
      call ranks_needing(l, need, nranks_seen)
      do k = 1, nranks_seen
        r = findloc(ranks, need(k), 1)
        send_node(pos(r)) = int(l, ip)
        pos(r) = pos(r) + 1
      end do
    end do
    call halo%init(comm, ranks, recv_first, send_first, send_node, width)

  contains

    !> Ranks other than me that own a node sharing a cell with owned node l.
    subroutine ranks_needing(l_, need_, n_)
      integer, intent(in) :: l_
      integer, intent(out) :: need_(9), n_
      integer :: o, ij(2)
      n_ = 0
      ij = lat%node_ij(l_)
      do dj = -1, 1
        do di = -1, 1
          ii = ij(1) + di
          jj = ij(2) + dj
          if (ii < 0 .or. ii > grid%nx .or. jj < 0 .or. jj > grid%ny) cycle
          o = part(grid%node_id(ii, jj))
          if (o == me) cycle
          dup = .false.
          do q = 1, n_
            if (need_(q) == o) dup = .true.
          end do
          if (.not. dup) then
            n_ = n_ + 1
            need_(n_) = o
          end if
        end do
      end do
      ! every such rank must be a neighbour we receive from (the relation is symmetric)
      do q = 1, n_
        if (findloc(ranks, need_(q), 1) == 0) error stop 'iem: halo plan is not symmetric'
      end do
    end subroutine ranks_needing
  end subroutine build_halo
end module iem_decomposition
