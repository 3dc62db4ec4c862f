!> Bands of a rank's chunks of cells for an evaluation whose pass over the nodes follows the
!> cells band by band (docs/architecture.md, "The node pass band by band"): after the chunks of
!> a band, the nodes that no later chunk has as a corner have all their cells' forces, and the
!> pass can update them while their values and forces are still in the processor's caches,
!> instead of in a second sweep over the whole state. On a rank with halo nodes the bands are
!> those of the interior chunks, and the nodes of D (the owned corners of boundary cells,
!> iem_cell_split) wait for the boundary chunks.
module iem_cell_bands
  use iem_cell_table, only: cell_table_t
  implicit none
  private
  public :: cell_bands_t, band_nodes_default

  !> The fewest nodes a band completes (their state and forces, about 48 bytes a node, stay in
  !> the processor's caches); a rank with fewer than twice as many owned nodes is not banded.
  integer, parameter :: band_nodes_default = 16384

  !> The bands of one rank's chunks (made once for its lattice).
  type :: cell_bands_t
    !> Whether the evaluation goes band by band (at least two bands; else nothing is
    !> allocated).
    logical :: active = .false.
    !> Band b is the chunks last_chunk(b - 1) + 1 .. last_chunk(b) of the table (last_chunk(0)
    !> = 0); after it, the nodes 1 .. done(b) but those of D are corners of no later chunk
    !> (done(n_bands) = n_owned).
    integer, allocatable :: last_chunk(:), done(:)
    !> The runs of consecutive nodes that band b completes: runs(:, r) = first, last node, for
    !> r = run_first(b) .. run_first(b + 1) - 1; those of b = n_bands + 1 are D's nodes (none
    !> without halo nodes), complete after the boundary chunks.
    integer, allocatable :: runs(:, :), run_first(:)
  contains
    procedure :: init => bands_init
    procedure :: n_bands => bands_n_bands
  end type cell_bands_t

contains

  !> The bands of the chunks of cells (on a rank with halo nodes, its interior chunks) of a
  !> rank with n_owned owned nodes, whose nodes d_node (ascending; none: absent) complete only
  !> after the other chunks, each band completing at least band_nodes nodes (default
  !> band_nodes_default); inactive with fewer than two bands.
  subroutine bands_init(this, cells, n_owned, d_node, band_nodes)
    class(cell_bands_t), intent(inout) :: this
    type(cell_table_t), intent(in) :: cells
    integer, intent(in) :: n_owned
    integer, intent(in), optional :: d_node(:)
    integer, intent(in), optional :: band_nodes
    integer, allocatable :: done(:), cq(:, :), d(:), runs(:, :), first(:)
    integer :: nc, j, m, low, nb, last, least, nr, k, l0, b

    least = band_nodes_default
    if (present(band_nodes)) least = band_nodes
    if (allocated(this%last_chunk)) deallocate(this%last_chunk, this%done, this%runs, &
                                               this%run_first)
    this%active = .false.
    nc = cells%n_chunks()
    if (n_owned < 2*least .or. nc < 2) return
    ! done(j): the nodes below the smallest corner of the chunks after j
    allocate(done(nc), cq(4, maxval(cells%chunks(2, :))))
    low = n_owned + 1
    do j = nc, 1, -1
      done(j) = min(n_owned, low - 1)
      if (cells%chunks(3, j) == 1) then
        ! consecutive rows: the first nodes of the two rows
        low = min(low, cells%chunks(4, j), cells%chunks(5, j))
      else
        call cells%chunk_corners(j, cq, m)
        low = min(low, minval(cq(:, 1:m)))
      end if
    end do
    ! cut a band where at least least more nodes are done, the last one at the end; a last
    ! band that completes fewer joins the one before
    allocate(this%last_chunk(nc), this%done(nc))
    nb = 0
    last = 0
    do j = 1, nc
      if (j < nc .and. done(j) - last < least) cycle
      if (j == nc .and. nb > 0 .and. done(j) - last < least) nb = nb - 1
      nb = nb + 1
      this%last_chunk(nb) = j
      this%done(nb) = done(j)
      last = done(j)
    end do
    if (nb < 2) then
      deallocate(this%last_chunk, this%done)
      return
    end if
    this%last_chunk = this%last_chunk(1:nb)
    this%done = this%done(1:nb)
    ! the runs: each band's nodes without D's, then D's
    if (present(d_node)) then
      d = d_node
    else
      allocate(d(0))
    end if
    ! (a band's runs: one more than D's nodes in it; D's: at most one a node)
    allocate(runs(2, nb + 2*size(d) + 1), first(nb + 2))
    nr = 0
    k = 1
    l0 = 1
    do b = 1, nb
      first(b) = nr + 1
      do while (l0 <= this%done(b))
        ! skip D's nodes, then run up to the next one or the band's end
        do while (k <= size(d))
          if (d(k) >= l0) exit
          k = k + 1
        end do
        if (k <= size(d)) then
          if (d(k) == l0) then
            l0 = l0 + 1
            cycle
          end if
        end if
        nr = nr + 1
        runs(1, nr) = l0
        runs(2, nr) = this%done(b)
        if (k <= size(d)) runs(2, nr) = min(this%done(b), d(k) - 1)
        l0 = runs(2, nr) + 1
      end do
    end do
    first(nb + 1) = nr + 1
    do k = 1, size(d)
      if (k > 1) then
        if (d(k) == d(k - 1) + 1) then
          runs(2, nr) = d(k)
          cycle
        end if
      end if
      nr = nr + 1
      runs(:, nr) = d(k)
    end do
    first(nb + 2) = nr + 1
    this%runs = runs(:, 1:nr)
    this%run_first = first
    this%active = .true.
  end subroutine bands_init

  !> The number of bands (0 when inactive).
  pure integer function bands_n_bands(this)
    class(cell_bands_t), intent(in) :: this
    bands_n_bands = 0
    if (this%active) bands_n_bands = size(this%last_chunk)
  end function bands_n_bands
end module iem_cell_bands
