!> Pieces of a distributed body (cells joined when they share a node), found on the ranks'
!> local lattices without any array over the whole body: a piece is labelled by its lowest
!> cell number; each rank joins its local nodes through its local cells (union-find), and
!> the labels of these local components travel through the halo until no rank lowers one.
module iem_pieces
  use mpi_f08, only: MPI_Comm, MPI_Allreduce, MPI_Gather, MPI_Gatherv, MPI_Bcast, &
                     MPI_Comm_rank, MPI_Comm_size, MPI_IN_PLACE, MPI_SUM, MPI_LOR, MPI_LOGICAL
  use iem_kinds, only: wp, ip, i8, mpi_wp, mpi_i8, mpi_ip
  use iem_local_lattice, only: local_lattice_t
  use iem_halo, only: halo_t
  use iem_sort, only: sort_i8, sum_by_label
  implicit none
  private
  public :: count_pieces, max_listed

  !> Most pieces listed (a cell centre of each piece but the largest, for the log).
  integer, parameter :: max_listed = 5

contains

  !> Pieces of the body held in the ranks' local lattices (cells joined through shared
  !> nodes): their number, and the centre of the lowest-numbered cell of each piece but the
  !> largest (most cells; ties: the lowest label), in ascending order of that cell's number,
  !> up to max_listed (n_listed of them). Same results on every rank. Collective.
  subroutine count_pieces(lat, halo, comm, n_pieces, piece_xy, n_listed)
    type(local_lattice_t), intent(in) :: lat
    type(halo_t), intent(inout) :: halo
    type(MPI_Comm), intent(in) :: comm
    integer(i8), intent(out) :: n_pieces
    real(wp), intent(out) :: piece_xy(2, max_listed)
    integer, intent(out) :: n_listed
    integer(i8), allocatable :: label(:)
    integer(ip), allocatable :: comp(:)
    integer(i8) :: listed(max_listed), cnt(1)
    integer :: c, k

    piece_xy = 0.0_wp
    n_listed = 0
    call local_components(lat, comp, label)
    call agree_labels(lat, halo, comm, comp, label)
    ! a piece is counted once: by the rank counting its lowest cell
    cnt = 0
    do c = 1, lat%n_cells
      if (lat%cell_counted(c)) then
        if (lat%cell_gid(c) == label(comp(lat%cell_nodes(1, c)))) cnt = cnt + 1
      end if
    end do
    call MPI_Allreduce(MPI_IN_PLACE, cnt, 1, mpi_i8(), MPI_SUM, comm)
    n_pieces = cnt(1)
    if (n_pieces <= 1) return
    call choose_listed(lat, comm, comp, label, listed)
    n_listed = count(listed >= 0)
    ! the centres of the listed cells, from the ranks that count them
    do c = 1, lat%n_cells
      if (.not. lat%cell_counted(c)) cycle
      do k = 1, n_listed
        if (lat%cell_gid(c) == listed(k)) then
          piece_xy(:, k) = 0.5_wp*(lat%node_xy(lat%cell_nodes(1, c)) + &
                                   lat%node_xy(lat%cell_nodes(3, c)))
        end if
      end do
    end do
    call MPI_Allreduce(MPI_IN_PLACE, piece_xy, size(piece_xy), mpi_wp(), MPI_SUM, comm)
  end subroutine count_pieces

  !> Components of the local nodes joined through the local cells (union-find): comp(l) the
  !> component of local node l (1..), label(k) the lowest cell number of component k.
  subroutine local_components(lat, comp, label)
    type(local_lattice_t), intent(in) :: lat
    integer(ip), allocatable, intent(out) :: comp(:)
    integer(i8), allocatable, intent(out) :: label(:)
    integer(ip), allocatable :: parent(:)
    integer :: c, q, l, n, r, k, qc(4)
    allocate(parent(lat%n_local), comp(lat%n_local))
    do l = 1, lat%n_local
      parent(l) = l
    end do
    do c = 1, lat%n_cells
      ! the cell's corners looked up once (each lookup finds the cell's chunk)
      qc = lat%corners(c)
      do q = 2, 4
        call join(qc(1), qc(q))
      end do
    end do
    ! number the components by their roots; a node of no cell keeps a label of its own
    n = 0
    comp = 0
    do l = 1, lat%n_local
      r = root(l)
      if (comp(r) == 0) then
        n = n + 1
        comp(r) = n
      end if
      comp(l) = comp(r)
    end do
    allocate(label(n), source=huge(0_i8))
    do c = 1, lat%n_cells
      k = comp(lat%cell_nodes(1, c))
      label(k) = min(label(k), lat%cell_gid(c))
    end do
  contains
    integer function root(a) result(r_)
      integer, intent(in) :: a
      r_ = a
      do while (parent(r_) /= r_)
        parent(r_) = parent(parent(r_))
        r_ = parent(r_)
      end do
    end function root
    subroutine join(a, b)
      integer(ip), intent(in) :: a, b
      integer :: ra, rb
      ra = root(a)
      rb = root(b)
      if (ra /= rb) parent(max(ra, rb)) = min(ra, rb)
    end subroutine join
  end subroutine local_components

  !> Lower each local component's label to the lowest over the piece: owners send their
  !> nodes' labels to the halo copies, each component takes the lowest of its nodes', until
  !> no rank lowers a label. Each round carries labels across one more rank boundary.
  subroutine agree_labels(lat, halo, comm, comp, label)
    type(local_lattice_t), intent(in) :: lat
    type(halo_t), intent(inout) :: halo
    type(MPI_Comm), intent(in) :: comm
    integer(ip), intent(in) :: comp(:)
    integer(i8), intent(inout) :: label(:)
    real(wp), allocatable :: y(:, :)
    logical :: changed(1)
    integer :: l
    ! labels travel as reals: exact below 2**53 cells
    allocate(y(halo%width, lat%n_local), source=0.0_wp)
    do
      do l = 1, lat%n_owned
        y(1, l) = real(label(comp(l)), wp)
      end do
      call halo%exchange(y)
      changed = .false.
      do l = lat%n_owned + 1, lat%n_local
        if (y(1, l) < real(label(comp(l)), wp)) then
          label(comp(l)) = int(y(1, l), i8)
          changed = .true.
        end if
      end do
      call MPI_Allreduce(MPI_IN_PLACE, changed, 1, MPI_LOGICAL, MPI_LOR, comm)
      if (.not. changed(1)) exit
    end do
  end subroutine agree_labels

  !> The labels of the pieces to list: up to max_listed lowest, without the largest piece's
  !> (most cells; ties: the lowest label); -1 past the last. Rank 0 gathers each rank's
  !> (label, cells it counts) pairs, one a local piece, and decides.
  subroutine choose_listed(lat, comm, comp, label, listed)
    type(local_lattice_t), intent(in) :: lat
    type(MPI_Comm), intent(in) :: comm
    integer(ip), intent(in) :: comp(:)
    integer(i8), intent(in) :: label(:)
    integer(i8), intent(out) :: listed(max_listed)
    integer(i8), allocatable :: mine(:), pairs(:), all_pairs(:), keys(:), size_of(:)
    integer(ip), allocatable :: n_of(:), displ(:)
    integer(ip) :: n_mine(1)
    integer :: c, k, n, m, rank, nranks
    integer(i8) :: big, best

    call MPI_Comm_rank(comm, rank)
    call MPI_Comm_size(comm, nranks)
    ! (label, count) of the cells this rank counts, one pair a label
    allocate(mine(lat%n_counted()))
    n = 0
    do c = 1, lat%n_cells
      if (lat%cell_counted(c)) then
        n = n + 1
        mine(n) = label(comp(lat%cell_nodes(1, c)))
      end if
    end do
    call sort_i8(mine)
    allocate(pairs(2*n))
    m = 0
    do k = 1, n
      if (k == 1) then
        m = m + 1
        pairs(2*m - 1:2*m) = [mine(k), 1_i8]
      else if (mine(k) /= mine(k - 1)) then
        m = m + 1
        pairs(2*m - 1:2*m) = [mine(k), 1_i8]
      else
        pairs(2*m) = pairs(2*m) + 1
      end if
    end do
    deallocate(mine)
    n_mine = 2*m
    allocate(n_of(merge(nranks, 0, rank == 0)), displ(merge(nranks, 0, rank == 0)))
    call MPI_Gather(n_mine, 1, mpi_ip(), n_of, 1, mpi_ip(), 0, comm)
    if (rank == 0) then
      displ(1) = 0
      do k = 2, nranks
        displ(k) = displ(k - 1) + n_of(k - 1)
      end do
      allocate(all_pairs(sum(int(n_of, i8))))
    else
      allocate(all_pairs(0))
    end if
    call MPI_Gatherv(pairs, n_mine(1), mpi_i8(), all_pairs, n_of, displ, mpi_i8(), 0, comm)
    deallocate(pairs)
    listed = -1
    if (rank == 0) then
      ! the distinct labels, ascending, and the cells of each
      call sum_by_label(all_pairs, keys, size_of)
      m = size(keys)
      ! the largest piece: the first of the most cells in ascending label order
      best = -1
      big = -1
      do k = 1, m
        if (size_of(k) > best) then
          best = size_of(k)
          big = keys(k)
        end if
      end do
      n = 0
      do k = 1, m
        if (n == max_listed) exit
        if (keys(k) == big) cycle
        n = n + 1
        listed(n) = keys(k)
      end do
    end if
    call MPI_Bcast(listed, max_listed, mpi_i8(), 0, comm)
  end subroutine choose_listed
end module iem_pieces
