!> Fragments of a fracturing body (docs/output.md, "/history/fracture"): the connected
!> components of its nodes over the intact edges (an edge is intact when at least one of the
!> cells holding it has an edge factor > 0), found on the ranks' local lattices without any
!> array over the whole body. As for the pieces of a body (iem_pieces), each rank joins its
!> local nodes (union-find), a component is labelled by its lowest global node number, and
!> the labels travel through the halo until no rank lowers one. Every edge with an owned end
!> is decided right on its owner (all the cells holding it are local there), so the labels
!> agree with the global components.
module iem_fragments
  use mpi_f08, only: MPI_Comm, MPI_Allreduce, MPI_Gather, MPI_Gatherv, MPI_Bcast, &
                     MPI_Comm_rank, MPI_Comm_size, MPI_IN_PLACE, MPI_LOR, MPI_LOGICAL, &
                     MPI_Isend, MPI_Irecv, MPI_Waitall, MPI_STATUSES_IGNORE, MPI_F_sync_reg
  use iem_kinds, only: wp, ip, i8, mpi_wp, mpi_i8, mpi_ip
  use iem_local_lattice, only: local_lattice_t
  use iem_halo, only: halo_t
  use iem_fracture, only: fracture_t, edge_factor
  use iem_sort, only: sort_i8, sum_by_label
  implicit none
  private
  public :: fragments_t, n_largest

  !> Fragment sizes reported: the node counts of the largest ones.
  integer, parameter :: n_largest = 5
  integer, parameter :: tag_labels = 117

  !> Work arrays of the fragment count of one rank, kept between counts (sized for the
  !> local lattice; grown when it grows, after a repartition).
  type :: fragments_t
    integer(ip), allocatable :: parent(:), comp(:)
    !> label(k): lowest global node number of local component k; cnt(k): its owned nodes.
    integer(i8), allocatable :: label(:), cnt(:)
    !> (label, owned nodes) pairs of this rank; rank 0: those of every rank.
    integer(i8), allocatable :: pairs(:), all_pairs(:)
  contains
    procedure :: count => fragments_count
  end type fragments_t

contains

  !> The number of fragments of the body (nodes joined through intact edges) and the node
  !> counts of its n_largest largest (descending, 0-padded), the same on every rank, from
  !> each rank's local lattice lat, halo plan halo and fracture state fr (materials of the
  !> cells: lat%mat). Collective.
  subroutine fragments_count(this, lat, halo, comm, fr, n_fragments, largest)
    class(fragments_t), intent(inout) :: this
    type(local_lattice_t), intent(in) :: lat
    type(halo_t), intent(inout) :: halo
    type(MPI_Comm), intent(in) :: comm
    type(fracture_t), intent(in) :: fr
    integer(i8), intent(out) :: n_fragments, largest(n_largest)
    integer(i8) :: res(n_largest + 1)
    integer :: n_comp, l, k, m, rank

    call ensure(this, lat%n_local)
    call local_components(this, lat, fr, n_comp)
    call agree_labels(this, halo, comm)
    ! owned nodes of each local component: one (label, count) pair a component with some
    this%cnt(1:n_comp) = 0
    do l = 1, lat%n_owned
      k = this%comp(l)
      this%cnt(k) = this%cnt(k) + 1
    end do
    m = 0
    do k = 1, n_comp
      if (this%cnt(k) == 0) cycle
      m = m + 1
      this%pairs(2*m - 1:2*m) = [this%label(k), this%cnt(k)]
    end do
    call MPI_Comm_rank(comm, rank)
    call merge_pairs(this, comm, rank, 2*m, res)
    call MPI_Bcast(res, n_largest + 1, mpi_i8(), 0, comm)
    n_fragments = res(1)
    largest = res(2:)
  end subroutine fragments_count

  !> Size the work arrays for n_local nodes (kept when large enough).
  subroutine ensure(this, n_local)
    type(fragments_t), intent(inout) :: this
    integer, intent(in) :: n_local
    if (allocated(this%parent)) then
      if (size(this%parent) >= n_local) return
      deallocate(this%parent, this%comp, this%label, this%cnt, this%pairs)
    end if
    allocate(this%parent(n_local), this%comp(n_local), this%label(n_local), &
             this%cnt(n_local), this%pairs(2*n_local))
  end subroutine ensure

  !> Components of the local nodes joined through the intact edges of the local cells:
  !> comp(l) the component of local node l (1..n_comp), label(k) the lowest global number
  !> of the nodes of component k.
  subroutine local_components(this, lat, fr, n_comp)
    type(fragments_t), intent(inout) :: this
    type(local_lattice_t), intent(in) :: lat
    type(fracture_t), intent(in) :: fr
    integer, intent(out) :: n_comp
    integer :: c, q, l, r, k, qc(4)
    do l = 1, lat%n_local
      this%parent(l) = l
    end do
    do c = 1, lat%n_cells
      ! the cell's corners looked up once (each lookup finds the cell's chunk)
      qc = lat%corners(c)
      do q = 1, 4
        ! an undamaged cell's edges are all intact
        if (fr%hit(c)) then
          if (edge_factor(fr%laws(lat%mat(c)), fr%kappa(:, c), q) <= 0.0_wp) cycle
        end if
        call join(qc(q), qc(mod(q, 4) + 1))
      end do
    end do
    ! number the components by their roots
    n_comp = 0
    this%comp(1:lat%n_local) = 0
    do l = 1, lat%n_local
      r = root(l)
      if (this%comp(r) == 0) then
        n_comp = n_comp + 1
        this%comp(r) = n_comp
        this%label(n_comp) = huge(0_i8)
      end if
      k = this%comp(r)
      this%comp(l) = k
      this%label(k) = min(this%label(k), lat%node_gid(l))
    end do
  contains
    integer function root(a) result(r_)
      integer, intent(in) :: a
      r_ = a
      do while (this%parent(r_) /= r_)
        this%parent(r_) = this%parent(this%parent(r_))
        r_ = this%parent(r_)
      end do
    end function root
    subroutine join(a, b)
      integer(ip), intent(in) :: a, b
      integer :: ra, rb
      ra = root(a)
      rb = root(b)
      if (ra /= rb) this%parent(max(ra, rb)) = min(ra, rb)
    end subroutine join
  end subroutine local_components

  !> Lower each local component's label to the lowest over its fragment: owners send their
  !> nodes' labels to the halo copies (through the halo plan and its buffers, one value a
  !> node), each component takes the lowest of its nodes', until no rank lowers a label.
  subroutine agree_labels(this, halo, comm)
    type(fragments_t), intent(inout) :: this
    type(halo_t), intent(inout) :: halo
    type(MPI_Comm), intent(in) :: comm
    logical :: changed(1)
    integer :: k, n, a, b, nb
    integer(i8) :: v
    nb = halo%n_neighbors
    do
      changed = .false.
      if (nb > 0) then
        ! labels travel as reals: exact below 2**53 nodes
        do k = 1, nb
          a = halo%recv_first(k) - halo%recv_first(1) + 1
          b = halo%recv_first(k + 1) - halo%recv_first(1)
          call MPI_Irecv(halo%recv_buf(a:b), b - a + 1, mpi_wp(), halo%rank(k), tag_labels, &
                         comm, halo%req(k))
        end do
        do k = 1, nb
          do n = halo%send_first(k), halo%send_first(k + 1) - 1
            halo%send_buf(n) = real(this%label(this%comp(halo%send_node(n))), wp)
          end do
          a = halo%send_first(k)
          b = halo%send_first(k + 1) - 1
          call MPI_Isend(halo%send_buf(a:b), b - a + 1, mpi_wp(), halo%rank(k), tag_labels, &
                         comm, halo%req(nb + k))
        end do
        call MPI_Waitall(2*nb, halo%req, MPI_STATUSES_IGNORE)
        call MPI_F_sync_reg(halo%recv_buf)
        a = halo%recv_first(1)
        do n = a, halo%recv_first(nb + 1) - 1
          v = int(halo%recv_buf(n - a + 1), i8)
          k = this%comp(n)
          if (v < this%label(k)) then
            this%label(k) = v
            changed = .true.
          end if
        end do
      end if
      call MPI_Allreduce(MPI_IN_PLACE, changed, 1, MPI_LOGICAL, MPI_LOR, comm)
      if (.not. changed(1)) exit
    end do
  end subroutine agree_labels

  !> Rank 0 gathers every rank's (label, owned nodes) pairs (n_mine values of this rank's)
  !> and sums them by label: res(1) the number of fragments, res(2:) the largest node counts.
  subroutine merge_pairs(this, comm, rank, n_mine, res)
    type(fragments_t), intent(inout) :: this
    type(MPI_Comm), intent(in) :: comm
    integer, intent(in) :: rank, n_mine
    integer(i8), intent(out) :: res(n_largest + 1)
    integer(ip), allocatable :: n_of(:), displ(:)
    integer(i8), allocatable :: keys(:), sizes(:)
    integer(ip) :: mine(1)
    integer :: nranks, k, m, j
    integer(i8) :: total, grown

    call MPI_Comm_size(comm, nranks)
    mine = int(n_mine, ip)
    allocate(n_of(merge(nranks, 0, rank == 0)), displ(merge(nranks, 0, rank == 0)))
    call MPI_Gather(mine, 1, mpi_ip(), n_of, 1, mpi_ip(), 0, comm)
    total = 0
    if (rank == 0) then
      displ(1) = 0
      do k = 2, nranks
        displ(k) = displ(k - 1) + n_of(k - 1)
      end do
      total = sum(int(n_of, i8))
    end if
    if (.not. allocated(this%all_pairs)) allocate(this%all_pairs(0))
    if (size(this%all_pairs, kind=i8) < total) then
      ! (the new size taken before the old array goes: its size is undefined after)
      grown = max(total, 2*size(this%all_pairs, kind=i8))
      deallocate(this%all_pairs)
      allocate(this%all_pairs(grown))
    end if
    call MPI_Gatherv(this%pairs, n_mine, mpi_i8(), this%all_pairs, n_of, displ, mpi_i8(), 0, &
                     comm)
    res = 0
    if (rank /= 0) return
    ! the distinct labels, ascending, and the owned nodes of each summed over the ranks
    call sum_by_label(this%all_pairs(1:total), keys, sizes)
    m = size(keys)
    res(1) = m
    call sort_i8(sizes)
    do j = 1, min(n_largest, m)
      res(1 + j) = sizes(m - j + 1)
    end do
  end subroutine merge_pairs
end module iem_fragments
